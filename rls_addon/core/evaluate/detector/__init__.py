"""Detectors of still roadside LiDARs: the protocol every detector meets (``protocol``)
and RLS's built-in one (``roadside.RoadsideDetector``), a module per step: background,
foreground (and ground), clustering, boxing (box_fit, priors), confidence."""

from .protocol import Detector, detect_frame, learn_sensors
from .roadside import RoadsideDetector

__all__ = ["Detector", "RoadsideDetector", "detect_frame", "learn_sensors"]

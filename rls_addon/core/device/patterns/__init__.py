"""Scan-pattern generators, one module per scanning family."""

from .base import ScanPattern, angles_from_directions, directions_from_angles

__all__ = ["ScanPattern", "angles_from_directions", "directions_from_angles"]

"""One frame of one LiDAR object, for scripts and tests (runs of frames x LiDARs go
through ``batch.make_run`` and the core's ``ScanRun``)."""

import bpy

from ..core.casting import caster_factory
from ..core.scan.session import ScanSession
from .sensor import read_settings, sensor_job
from .source import BlenderScene


def scan_lidar(obj, frame=None, backend=None, settings=None, session=None, source=None):
    """Scan ``frame`` (default: the current one) of LiDAR ``obj``; returns (ScanResult,
    info dict for the sidecar).

    backend   ray-casting backend name (default: the LiDAR's own setting)
    settings  ``LidarSettings`` to use instead of the object's
    session   a ``core.session.ScanSession`` to keep prepared scenes in over calls
    source    a ``BlenderScene`` to keep read meshes in over calls"""
    scene = obj.users_scene[0] if obj.users_scene else bpy.context.scene
    job = sensor_job(obj, settings or read_settings(obj))
    if session is None:
        session = ScanSession(caster_factory(backend or job.settings.backend)[0])
    source = source or BlenderScene(scene)
    if frame is None:
        frame = scene.frame_current
    elif scene.frame_current != frame:
        scene.frame_set(frame)
    return session.scan(source, obj.name, job.preset, job.settings.scan, frame)

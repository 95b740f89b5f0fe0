"""LiDAR objects: recognising them and turning their settings into core inputs."""

import numpy as np

from ..core.engine import ScanSettings
from ..core.errors import SceneError

DEFAULT_PRESET = "generic_uniform32"


def lidar_settings(obj):
    """The ``rls_lidar`` property group of an object, or None."""
    return getattr(obj, "rls_lidar", None)


def is_lidar(obj):
    s = lidar_settings(obj)
    return bool(s is not None and s.is_lidar)


def lidar_objects(scene):
    """LiDAR objects of a scene, sorted by name."""
    return sorted((o for o in scene.objects if is_lidar(o)), key=lambda o: o.name)


def find_lidar(scene, name):
    """The LiDAR object called ``name``, with an error that lists the LiDARs there are."""
    obj = scene.objects.get(name)
    names = [o.name for o in lidar_objects(scene)]
    if obj is None:
        raise SceneError(f"no object named '{name}' in scene '{scene.name}'; "
                         f"LiDAR objects: {', '.join(names) or 'none'}")
    if not is_lidar(obj):
        raise SceneError(f"object '{name}' is not a LiDAR; LiDAR objects: {', '.join(names) or 'none'}")
    return obj


def scan_inputs(obj):
    """(DevicePreset, ScanSettings) from a LiDAR object's properties.

    The one place where the panel's properties become the core's settings: overrides
    left off take the preset's values (None)."""
    from .preset_catalog import resolve

    s = lidar_settings(obj)
    preset = resolve(s.preset_id or DEFAULT_PRESET)
    settings = ScanSettings(
        seed=int(s.seed),
        frame_space=s.frame_space.lower(),
        noise=bool(s.noise),
        dropout=bool(s.dropout),
        min_range_m=float(s.min_range) if s.use_min_range else None,
        max_range_m=float(s.max_range) if s.use_max_range else None,
        noise_sigma_m=float(s.noise_sigma) if s.use_noise_sigma else None,
        motion=s.motion,
        substeps=int(s.substeps),
        ghosting=bool(s.ghosting),
    )
    return preset, settings


def sensor_pose(obj):
    """4x4 float64 world pose of the (evaluated) sensor object."""
    return np.array(obj.matrix_world, dtype=np.float64)

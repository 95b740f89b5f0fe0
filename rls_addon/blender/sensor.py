"""LiDAR objects: recognising them and reading their settings, in one place."""

import os

import numpy as np

from ..core.errors import OutputError, SceneError
from ..core.labels import label_ids
from ..core.scan.run import SensorJob
from ..core.scan.settings import LidarSettings, OutputSettings, ScanSettings

DEFAULT_PRESET = "generic_uniform32"


def lidar_props(obj):
    """The ``rls_lidar`` property group of an object, or None."""
    return getattr(obj, "rls_lidar", None)


def is_lidar(obj):
    s = lidar_props(obj)
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


def read_settings(obj):
    """The core's ``LidarSettings`` of a LiDAR object: the one place where the panel's
    properties become settings. Overrides left off take the preset's values (None)."""
    s = lidar_props(obj)
    scan = ScanSettings(
        seed=int(s.seed),
        frame_space=s.frame_space,
        noise=bool(s.noise),
        dropout=bool(s.dropout),
        min_range_m=float(s.min_range) if s.use_min_range else None,
        max_range_m=float(s.max_range) if s.use_max_range else None,
        noise_sigma_m=float(s.noise_sigma) if s.use_noise_sigma else None,
        motion=s.motion,
        substeps=int(s.substeps),
        ghosting=bool(s.ghosting),
        sweep_start_deg=float(s.sweep_start) if s.use_sweep_start else None,
        weather=weather_spec_of(s),
        detection=s.detection,
        footprint=s.footprint,
        return_mode=s.return_mode,
        rotation_hz=float(s.rotation_hz) if s.use_rotation_hz else None,
        lidar_mode=None if s.lidar_mode in ("", "DEFAULT") else s.lidar_mode,
    )
    output = OutputSettings(directory=s.output_dir, format=s.file_format,
                            fields=("x", "y", "z") + tuple(sorted(s.fields)),
                            template=s.name_template, ground_truth=bool(s.ground_truth),
                            object_classes=tuple(label_ids(s.object_classes)),
                            point_type=s.point_type, crs=s.crs.strip() or None)
    return LidarSettings(preset=s.preset_id or DEFAULT_PRESET, scan=scan, output=output,
                         backend=s.backend)


def weather_spec_of(s):
    """The weather spec of a LiDAR's properties (None: clear)."""
    if s.weather == "fog":
        return f"fog:visibility={float(s.fog_visibility):g}"
    if s.weather == "rain":
        return f"rain:rate={float(s.precipitation_rate):g}"
    if s.weather == "snow":
        return f"snow:rate={float(s.precipitation_rate):g},type={s.snow_type}"
    return None


def sensor_job(obj, settings=None):
    """A run's ``SensorJob`` for LiDAR ``obj``: its settings (``read_settings``, or
    ``settings`` already read and overridden) with the device preset resolved."""
    from ..core.scan.settings import preset_in_modes
    from .preset_catalog import resolve

    settings = settings or read_settings(obj)
    return SensorJob(obj.name, settings, preset_in_modes(resolve(settings.preset), settings.scan))


def absolute_output(settings):
    """``settings`` with its output folder made absolute (a ``//`` folder is relative
    to the .blend file, which must be saved then)."""
    import bpy

    path = settings.output.directory
    if not path or not path.strip():
        raise OutputError("no output folder set")
    if path.startswith("//") and not bpy.data.filepath:
        raise OutputError(f"output folder '{path}' is relative to the .blend file, which is not "
                          f"saved yet: save the file or choose an absolute folder")
    return settings.override(directory=os.path.normpath(bpy.path.abspath(path)))


def sensor_pose(obj):
    """4x4 float64 world pose of the (evaluated) sensor object."""
    return np.array(obj.matrix_world, dtype=np.float64)

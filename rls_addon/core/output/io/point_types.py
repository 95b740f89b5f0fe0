"""Point layouts of vendor ROS drivers: RLS points as the records those drivers publish.

A *point type* is an exact packed little-endian numpy dtype (field names, order and
types as the driver defines them) and a conversion from ``POINT_DTYPE`` points with
the units the driver uses. The records feed any encoder of packed structured arrays
(``pcd.encode``, ``ply.encode``, the ROS 2 bag writer's ``PointCloud2``).

    rls       x y z intensity ring time label instance ghost (today's fields, lossless
              apart from float32 coordinates; the default)
    velodyne  velodyne_pcl::PointXYZIRT: x y z intensity(0..255) ring time(s, float32)
    ouster    ouster_ros::Point: x y z intensity t(ns) reflectivity ring ambient range(mm)
    hesai     the Hesai ROS 2 driver's PointCloud2: x y z intensity(0..255) ring
              timestamp(absolute s, float64)
    autoware  autoware::point_types::PointXYZIRC: x y z intensity(uint8) return_type channel

Each field's type, unit and the value RLS writes (including fields RLS cannot know,
such as Ouster's ambient light) are listed by ``point_type_fields`` and in
docs/formats.md, with the repository and path of each driver's definition.

Rings: RLS's ``ring`` is the row of the device's channel table (firing order).
Velodyne's driver numbers rings by elevation from the lowest beam up and Ouster's from
the top beam down; pass the table's elevations (``channel_elevations_deg``) to get
those numberings, else the table row is written as it is.
"""

from dataclasses import dataclass

import numpy as np

from ...choices import Choices
from ...errors import OutputError, SettingsError
from .fields import DEFAULT_FIELDS, pack

POINT_TYPE_CHOICES = Choices("point type", [
    ("rls", "RLS (all fields)", ("x y z intensity (0..1) ring time (s) label instance ghost: "
                                 "every field RLS simulates")),
    ("velodyne", "Velodyne PointXYZIRT", ("velodyne_pointcloud: x y z intensity (0..255) ring "
                                          "time (float32 s since sweep start)")),
    ("ouster", "Ouster Point", ("ouster-ros: x y z intensity t (uint32 ns since sweep start) "
                                "reflectivity ring ambient range (mm)")),
    ("hesai", "Hesai PointXYZIRT", ("HesaiLidar_ROS_2.0: x y z intensity (0..255) ring "
                                    "timestamp (float64 absolute s)")),
    ("autoware", "Autoware PointXYZIRC", ("autoware_point_types: x y z intensity (uint8) "
                                          "return_type channel")),
])
POINT_TYPES = POINT_TYPE_CHOICES.ids
DEFAULT_POINT_TYPE = "rls"

# The POINT_DTYPE fields the vendor layouts are made from.
_NEEDED = ("x", "y", "z", "range", "intensity", "ring", "time")
# Autoware's ReturnType enum: 1 = SINGLE_STRONGEST (RLS returns one echo per ray).
AUTOWARE_SINGLE_STRONGEST = 1


@dataclass(frozen=True)
class FieldSpec:
    """One field of a point type: ``dtype`` is its exact little-endian numpy type."""
    name: str
    dtype: np.dtype
    unit: str
    value: str  # what RLS writes there


@dataclass(frozen=True)
class PointType:
    name: str
    fields: tuple  # FieldSpec, in the driver's order
    source: str    # repository and path of the driver's definition

    @property
    def dtype(self):
        return np.dtype([(f.name, f.dtype) for f in self.fields])


def _f(name, dtype, unit, value):
    return FieldSpec(name, np.dtype(dtype), unit, value)


_XYZ = (
    _f("x", "<f4", "m", "x, sensor or world frame as the cloud is"),
    _f("y", "<f4", "m", "y"),
    _f("z", "<f4", "m", "z"),
)

_LAYOUTS = {
    "rls": PointType("rls", _XYZ + (
        _f("intensity", "<f4", "0..1", "RLS intensity"),
        _f("ring", "<u2", "index", "row of the device's channel table"),
        _f("time", "<f8", "s", "seconds since the start of the sweep"),
        _f("label", "<u4", "id", "semantic label (rls_addon.core.labels)"),
        _f("instance", "<u4", "id", "stable per-object id, 0 = none"),
        _f("ghost", "u1", "0/1", "1 for a ghost point from a specular bounce"),
    ), "rls_addon/core/output/io/fields.py (FILE_TYPES)"),
    "velodyne": PointType("velodyne", _XYZ + (
        _f("intensity", "<f4", "0..255", "255 * RLS intensity"),
        _f("ring", "<u2", "index", "ring by elevation, 0 = lowest beam (with "
                                   "channel_elevations_deg), else the table row"),
        _f("time", "<f4", "s", "seconds since the start of the sweep"),
    ), "ros-drivers/velodyne: velodyne_pcl/include/velodyne_pcl/point_types.h (PointXYZIRT); "
       "fields as published: velodyne_pointcloud/src/lib/pointcloudXYZIRT.cpp (ros2)"),
    "ouster": PointType("ouster", _XYZ + (
        _f("intensity", "<f4", "0..255", "255 * RLS intensity (the sensor's signal is a "
                                         "photon count; RLS has no photon model)"),
        _f("t", "<u4", "ns", "nanoseconds since the start of the sweep"),
        _f("reflectivity", "<u2", "0..100", "round(100 * RLS intensity): Ouster's "
                                            "calibrated reflectivity of a diffuse target"),
        _f("ring", "<u2", "index", "beam row, 0 = top beam (with channel_elevations_deg), "
                                   "else the table row"),
        _f("ambient", "<u2", "counts", "0: RLS does not simulate ambient (near-IR) light"),
        _f("range", "<u4", "mm", "round(1000 * range)"),
    ), "ouster-lidar/ouster-ros: ouster-ros/include/ouster_ros/os_point.h (ros2 branch; "
       "include/ouster_ros/os_point.h on master)"),
    "hesai": PointType("hesai", _XYZ + (
        _f("intensity", "<f4", "0..255", "round(255 * RLS intensity): the driver publishes "
                                         "the SDK's uint8 intensity as float32"),
        _f("ring", "<u2", "index", "row of the device's channel table (laser index)"),
        _f("timestamp", "<f8", "s", "absolute: start_time_s + seconds since sweep start"),
    ), "HesaiTechnology/HesaiLidar_ROS_2.0: src/manager/source_driver_ros2.hpp (ToRosMsg); "
       "SDK point: HesaiTechnology/HesaiLidar_SDK_2.0: libhesai/lidar_types.h"),
    "autoware": PointType("autoware", _XYZ + (
        _f("intensity", "u1", "0..255", "round(255 * RLS intensity)"),
        _f("return_type", "u1", "enum", f"{AUTOWARE_SINGLE_STRONGEST} (SINGLE_STRONGEST): "
                                        "one return per ray"),
        _f("channel", "<u2", "index", "row of the device's channel table"),
    ), "autowarefoundation/autoware_core: common/autoware_point_types/include/autoware/"
       "point_types/types.hpp (PointXYZIRC)"),
}
assert tuple(_LAYOUTS) == POINT_TYPES


def point_type(name):
    """The ``PointType`` called ``name``; ``SettingsError`` naming the valid ones."""
    return _LAYOUTS[POINT_TYPE_CHOICES.check(name)]


def point_type_fields(name):
    """The fields of point type ``name``: a tuple of ``FieldSpec`` (name, numpy dtype,
    unit, what RLS writes), in the driver's order."""
    return point_type(name).fields


def point_type_dtype(name):
    """The exact packed little-endian structured dtype of point type ``name``."""
    return point_type(name).dtype


def elevation_rings(channels, elevations_deg, lowest_first=True):
    """Ring numbers by elevation for table rows ``channels`` (N,) uint16, given the
    table's elevations (C,) in degrees: 0 = lowest beam (``lowest_first``, Velodyne)
    or 0 = top beam (Ouster). Equal elevations keep table order. Returns (N,) uint16."""
    el = np.asarray(elevations_deg, dtype=np.float64).reshape(-1)
    ch = np.asarray(channels)
    if ch.size and int(ch.max()) >= el.size:
        raise OutputError(f"ring {int(ch.max())} is outside the channel table "
                          f"({el.size} elevations given)")
    order = np.argsort(el if lowest_first else -el, kind="stable")
    rank = np.empty(el.size, dtype=np.uint16)
    rank[order] = np.arange(el.size, dtype=np.uint16)
    return rank[ch.astype(np.intp)]


def _scaled_uint(values, scale, top):
    """round(values * scale) clipped to 0..top, as float64 (exact for the integer range)."""
    return np.clip(np.rint(np.asarray(values, dtype=np.float64) * scale), 0, top)


def _intensity01(points):
    return np.clip(points["intensity"].astype(np.float64), 0.0, 1.0)


def to_point_type(points, name, start_time_s=0.0, channel_elevations_deg=None):
    """``points`` (N,) of ``POINT_DTYPE`` as records (N,) of point type ``name``'s dtype.

    start_time_s            absolute time (s, e.g. Unix time) of the sweep's start, for
                            absolute per-point timestamps (``hesai``); others ignore it
    channel_elevations_deg  (C,) elevation of each channel-table row, for the
                            ``velodyne`` and ``ouster`` ring numberings (see module doc)

    Units are converted as the drivers publish them (``point_type_fields`` says how);
    integer fields are rounded and clipped to their range.
    """
    layout = point_type(name)
    if name == "rls":
        return pack(points, DEFAULT_FIELDS)
    missing = [f for f in _NEEDED if f not in (points.dtype.names or ())]
    if missing:
        raise OutputError(f"points lack field(s) {', '.join(missing)} for point type {name!r}")
    out = np.zeros(len(points), dtype=layout.dtype)
    for f in ("x", "y", "z"):
        out[f] = points[f]
    i01 = _intensity01(points)
    ring = points["ring"]
    if channel_elevations_deg is not None and name in ("velodyne", "ouster"):
        ring = elevation_rings(ring, channel_elevations_deg, lowest_first=(name == "velodyne"))
    time = points["time"].astype(np.float64)
    if name == "velodyne":
        out["intensity"] = i01 * 255.0
        out["ring"] = ring
        out["time"] = time
    elif name == "ouster":
        out["intensity"] = i01 * 255.0
        out["t"] = _scaled_uint(time, 1e9, np.iinfo(np.uint32).max)
        out["reflectivity"] = _scaled_uint(i01, 100.0, 100)
        out["ring"] = ring
        out["ambient"] = 0
        out["range"] = _scaled_uint(points["range"], 1000.0, np.iinfo(np.uint32).max)
    elif name == "hesai":
        out["intensity"] = _scaled_uint(i01, 255.0, 255)
        out["ring"] = ring
        out["timestamp"] = float(start_time_s) + time
    elif name == "autoware":
        out["intensity"] = _scaled_uint(i01, 255.0, 255)
        out["return_type"] = AUTOWARE_SINGLE_STRONGEST
        out["channel"] = ring
    else:  # a layout in _LAYOUTS without a conversion: a programming error
        raise SettingsError(f"point type {name!r} has no conversion")
    return out


__all__ = [
    "DEFAULT_POINT_TYPE",
    "POINT_TYPES",
    "POINT_TYPE_CHOICES",
    "FieldSpec",
    "PointType",
    "elevation_rings",
    "point_type",
    "point_type_dtype",
    "point_type_fields",
    "to_point_type",
]

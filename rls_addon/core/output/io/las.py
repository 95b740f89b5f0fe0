"""LAS 1.4 point clouds (ASPRS), written with ``laspy`` (imported when first needed).

One file holds one or more clouds in the world frame, e.g. one (sensor, frame) cloud as a
scan run writes it, or several sensors' clouds of one frame (``LasWriter.write_merged``).
A per-run merged file (every frame of a run in one file) is not offered: it would hold
the whole run in memory; write per frame and merge with a LAS tool if you need one.

Point data record format 6 (LAS 1.4 base format with GPS time), per point:

    X Y Z               int32, world coordinates = offset + scale * XYZ (metres)
    intensity           uint16, round(65535 * RLS intensity 0..1)
    return_number       the point's return_index of its pulse's num_returns (1 of 1 for
                        a pulse with one echo)
    classification      ASPRS class from the RLS label (``ASPRS_CLASS``)
    point_source_id     the sensor: 1..K in the order the run names its sensors
    gps_time            float64 s, the point's absolute time (``gps_time``)
    extra bytes         ring uint16, label uint32, instance uint32, ghost uint8

Times: RLS absolute times are Unix (UTC) seconds (the sweep's start + the point's time
within the sweep). From 1980-01-06 on they are written as Adjusted Standard GPS Time
(GPS seconds - 1e9, global encoding bit 0 set; leap seconds from ``LEAP_SECONDS``); an
earlier value means the run has no absolute clock (its start time was left at 0) and is
written as given, as GPS week time (bit 0 clear): seconds since the run's start.
"""

import datetime
import re

import numpy as np

from ....version import VERSION
from ...errors import OutputError, RLSError, SettingsError
from ...labels import DEFAULT_LABELS, NAME_TO_ID
from ...points import POINT_DTYPE
from .atomic import atomic_write_bytes

DEFAULT_SCALE = 1e-4    # m per integer step: 0.1 mm, +-214 km around the offset
OFFSET_STEP = 1000.0    # automatic offsets: the clouds' minimum, floored to whole km
POINT_FORMAT = 6

# ASPRS standard point classes for point data record formats 6-10 (LAS 1.4 R15): the
# classes RLS uses. 64-255 are user definable; 23-63 are reserved.
ASPRS_NAMES = {0: "Created, never classified", 1: "Unclassified", 2: "Ground",
               3: "Low Vegetation", 4: "Medium Vegetation", 5: "High Vegetation",
               6: "Building", 7: "Low Point (noise)", 9: "Water", 10: "Rail",
               11: "Road Surface", 17: "Bridge Deck", 18: "High Noise",
               19: "Overhead Structure"}
USER_CLASS_BASE = 64
# RLS label name -> ASPRS class: a standard class where one means the same thing, else
# the user-definable class 64 + label id (the label itself is also kept as an extra byte).
_STANDARD = {"unlabeled": 1, "road": 11, "sidewalk": 2, "building": 6, "vegetation": 5,
             "terrain": 2, "water": 9, "ground": 2, "weather": 18}
ASPRS_CLASS = {i: _STANDARD.get(name, USER_CLASS_BASE + i) for i, name in DEFAULT_LABELS.items()}
UNMAPPED_CLASS = 1  # labels beyond the user-definable range: Unclassified

EXTRA_DIMS = (
    ("ring", np.uint16, "RLS ring: channel-table row"),
    ("label", np.uint32, "RLS semantic label id"),
    ("instance", np.uint32, "RLS stable object id, 0 none"),
    ("ghost", np.uint8, "1: ghost from a glossy bounce"),
)

# Unix time of the GPS epoch (1980-01-06T00:00:00Z) and the UTC dates from which
# GPS - UTC grew by one second (IERS Bulletin C); 18 s since 2017-01-01.
GPS_EPOCH_UNIX = 315_964_800
LEAP_SECONDS = ("1981-07-01", "1982-07-01", "1983-07-01", "1985-07-01", "1988-01-01",
                "1990-01-01", "1991-01-01", "1992-07-01", "1993-07-01", "1994-07-01",
                "1996-01-01", "1997-07-01", "1999-01-01", "2006-01-01", "2009-01-01",
                "2012-07-01", "2015-07-01", "2017-01-01")
_LEAP_UNIX = np.array([datetime.datetime.fromisoformat(d).replace(
    tzinfo=datetime.UTC).timestamp() for d in LEAP_SECONDS])
ADJUSTED_GPS_OFFSET = 1e9
_EPSG = re.compile(r"^EPSG:(\d{4,6})$", re.IGNORECASE)


def _laspy():
    try:
        import laspy
    except ImportError:
        raise RLSError("writing LAS files needs the Python package laspy: "
                       "pip install laspy==2.7.0 (into Blender's Python: "
                       "<blender>/python/bin/python -m pip install laspy==2.7.0)") from None
    return laspy


def asprs_classes(labels):
    """ASPRS classes (N,) uint8 for RLS labels (N,) (``ASPRS_CLASS``; other labels below
    192 map to 64 + label, the rest to Unclassified)."""
    labels = np.asarray(labels, dtype=np.int64)
    table = np.array([ASPRS_CLASS.get(i, USER_CLASS_BASE + i)
                      for i in range(256 - USER_CLASS_BASE)], dtype=np.uint8)
    inside = (labels >= 0) & (labels < table.size)
    return np.where(inside, table[np.clip(labels, 0, table.size - 1)],
                    UNMAPPED_CLASS).astype(np.uint8)


def gps_time(unix_s):
    """LAS GPS time of Unix (UTC) times ``unix_s`` (N,) s: (values (N,) float64, standard)
    where ``standard`` says whether they are Adjusted Standard GPS Time (all times from
    the GPS epoch on) or, for a relative clock (times before it), the input itself."""
    t = np.asarray(unix_s, dtype=np.float64)
    if t.size == 0 or float(t.min()) < GPS_EPOCH_UNIX:
        if t.size and float(t.max()) >= GPS_EPOCH_UNIX:
            raise OutputError("a LAS file cannot mix absolute times and a relative clock: "
                              "give every cloud's start time as Unix seconds, or none")
        return t.copy(), False
    leap = np.searchsorted(_LEAP_UNIX, t, side="right")
    return t - GPS_EPOCH_UNIX + leap - ADJUSTED_GPS_OFFSET, True


def _crs(crs):
    if crs is None:
        return None
    m = _EPSG.match(str(crs).strip())
    if not m:
        raise SettingsError(f"CRS must be written 'EPSG:<code>', e.g. 'EPSG:25832'; got {crs!r}")
    try:
        import pyproj
    except ImportError:
        raise RLSError("a LAS CRS needs the Python package pyproj: pip install pyproj==3.7.2") from None
    try:
        return pyproj.CRS.from_epsg(int(m.group(1)))
    except pyproj.exceptions.CRSError as exc:
        raise SettingsError(f"unknown CRS {crs!r}: {exc}") from None


def _scales(scale):
    s = np.broadcast_to(np.asarray(scale, dtype=np.float64), (3,)).copy()
    if not np.all(np.isfinite(s)) or np.any(s <= 0):
        raise SettingsError(f"LAS scale must be positive, got {scale!r}")
    return s


def auto_offset(xyz):
    """Offsets (3,) for world coordinates (N, 3): their minimum floored to whole km."""
    if len(xyz) == 0:
        return np.zeros(3)
    return np.floor(xyz.min(axis=0) / OFFSET_STEP) * OFFSET_STEP


def _integers(xyz, offset, scale):
    q = np.rint((xyz - offset) / scale)
    lo, hi = np.iinfo(np.int32).min, np.iinfo(np.int32).max
    bad = ~((q >= lo) & (q <= hi))  # NaN too: it would be cast to -2^31
    if bad.any():
        axis = "xyz"[int(np.argwhere(bad)[0][1])]
        raise OutputError(f"{axis} coordinates do not fit LAS's 32-bit integers with offset "
                          f"{offset.tolist()} and scale {scale.tolist()}: set an offset near "
                          f"the scene or a coarser scale")
    return q.astype(np.int32)


class LasWriter:
    """Writes the LAS files of one run.

    sensors    the run's sensor names, in order: point_source_id 1..K
    scale      metres per integer step, one value or (3,) (default 0.1 mm)
    offset     (3,) world offset in metres; None: per file, the minimum of its points
               floored to whole kilometres
    crs        'EPSG:<code>' of the world frame (a WKT CRS record; needs pyproj), or None
    overwrite  replace existing files (else an existing file is an OutputError)

    Files are written atomically (complete or absent), with ``.las`` as given in the path.
    """

    def __init__(self, sensors, *, scale=DEFAULT_SCALE, offset=None, crs=None, overwrite=False):
        names = [str(s) for s in sensors]
        if len(set(names)) != len(names):
            raise SettingsError(f"sensor names repeat: {names}")
        if len(names) > 65535:
            raise SettingsError("LAS point source ids hold at most 65535 sensors")
        self.source_ids = {name: i + 1 for i, name in enumerate(names)}
        self.scale = _scales(scale)
        self.offset = None if offset is None else np.asarray(offset, dtype=np.float64).reshape(3)
        self.crs = _crs(crs)
        self.overwrite = bool(overwrite)

    def source_id(self, sensor):
        try:
            return self.source_ids[str(sensor)]
        except KeyError:
            raise SettingsError(f"unknown sensor {sensor!r}; this run has "
                                + ", ".join(self.source_ids)) from None

    def write(self, path, sensor, points, start_time_s):
        """Write one cloud: ``points`` (N,) ``POINT_DTYPE`` in the world frame, of
        ``sensor``, whose sweep started at ``start_time_s`` (Unix s, or run-relative).
        Returns the path."""
        return self.write_merged(path, [(sensor, points, start_time_s)])

    def write_merged(self, path, clouds):
        """Write several clouds into one file: ``clouds`` is an iterable of
        (sensor, points (N,) world frame, sweep start s). Returns the path."""
        try:
            las = self.build(clouds)
        except OutputError as exc:
            raise OutputError(f"cannot write {path}: {exc}") from None
        return atomic_write_bytes(path, las.write, overwrite=self.overwrite)

    def build(self, clouds):
        """The ``laspy.LasData`` of ``clouds`` (see ``write_merged``), not yet written."""
        laspy = _laspy()
        clouds = list(clouds)
        pts = [np.asarray(p) for _, p, _ in clouds]
        ids = np.concatenate([np.full(len(p), self.source_id(s), np.uint16)
                              for (s, _, _), p in zip(clouds, pts)] or [np.zeros(0, np.uint16)])
        points = np.concatenate(pts) if pts else np.zeros(0, dtype=POINT_DTYPE)
        start = np.concatenate([np.full(len(p), float(t0)) for (_, _, t0), p in zip(clouds, pts)]
                               or [np.zeros(0)])
        times, standard = gps_time(start + points["time"].astype(np.float64))

        xyz = np.stack([points["x"], points["y"], points["z"]], axis=1).astype(np.float64)
        offset = auto_offset(xyz) if self.offset is None else self.offset
        header = laspy.LasHeader(point_format=POINT_FORMAT, version="1.4")
        header.scales, header.offsets = self.scale, offset
        header.add_extra_dims([laspy.ExtraBytesParams(name=n, type=t, description=d)
                               for n, t, d in EXTRA_DIMS])
        header.system_identifier = "RLS LiDAR simulation"
        header.generating_software = f"RLS {VERSION}"
        header.global_encoding.gps_time_type = (laspy.header.GpsTimeType.STANDARD if standard
                                                else laspy.header.GpsTimeType.WEEK_TIME)
        if standard and len(start):
            # the file's date: the (UTC) day of its first sweep, so equal runs write
            # equal bytes
            header.creation_date = _date(float(start.min()))
        if self.crs is not None:
            header.add_crs(self.crs)

        las = laspy.LasData(header)
        q = _integers(xyz, offset, self.scale)
        las.X, las.Y, las.Z = q[:, 0], q[:, 1], q[:, 2]
        las.intensity = np.clip(np.rint(points["intensity"].astype(np.float64) * 65535),
                                0, 65535).astype(np.uint16)
        names = points.dtype.names
        number = np.ones(len(points), np.uint8)
        if "return_index" in names:  # LAS 1.4 point format 6 holds 1..15
            number = np.clip(points["return_index"], 1, 15).astype(np.uint8)
        count = np.clip(points["num_returns"], number, 15).astype(np.uint8) \
            if "num_returns" in names else number.copy()
        las.return_number, las.number_of_returns = number, count
        las.classification = asprs_classes(points["label"])
        las.point_source_id = ids
        las.gps_time = times
        for name, dtype, _ in EXTRA_DIMS:
            setattr(las, name, points[name].astype(dtype))
        las.update_header()
        return las


# The fields a scan's LAS file holds (``write_scan``), as its sidecar lists them
SCAN_FIELDS = ("x", "y", "z", "intensity", "gps_time", "classification", "point_source_id",
               "ring", "label", "instance", "ghost")


def write_scan(cloud):
    """Write one scan's cloud (``formats.Cloud``) as a LAS file in world coordinates:
    its point source id from the run's sensors, the output's offset and CRS. Returns
    the fields written."""
    from .sidecar import points_to_world

    names = cloud.sensors if cloud.sensor in cloud.sensors else cloud.sensors + (cloud.sensor,)
    writer = LasWriter(names, offset=cloud.output.las_offset, crs=cloud.output.crs,
                       overwrite=cloud.overwrite)
    writer.write(cloud.path, cloud.sensor,
                 points_to_world(cloud.points, cloud.info, str(cloud.path)),
                 cloud.info.get("timestamp_s", 0.0))
    return list(SCAN_FIELDS)


def check_output(output):
    """Before a run: laspy is there (and pyproj for a CRS), the offset and CRS valid."""
    _laspy()
    LasWriter(("sensor",), offset=output.las_offset, crs=output.crs)


def count_points(path):
    """Points in a LAS file, from its header."""
    with _laspy().open(str(path)) as f:
        return int(f.header.point_count)


def _date(unix_s):
    """The UTC date of Unix time ``unix_s``; ``OutputError`` beyond the dates a LAS
    header (and Python) holds."""
    try:
        return datetime.datetime.fromtimestamp(unix_s, datetime.UTC).date()
    except (OverflowError, ValueError, OSError):
        raise OutputError(f"its first sweep's time, {unix_s:g} s, is beyond the dates a LAS "
                          "header holds (years 1 to 9999): give a start time (--start-time) "
                          "within them") from None


def class_table():
    """(label id, label name, ASPRS class, class name) rows of ``ASPRS_CLASS``."""
    return [(i, DEFAULT_LABELS[i], c, ASPRS_NAMES.get(c, "user definable"))
            for i, c in sorted(ASPRS_CLASS.items())]


assert set(_STANDARD) <= set(NAME_TO_ID)

__all__ = ["ASPRS_CLASS", "ASPRS_NAMES", "DEFAULT_SCALE", "EXTRA_DIMS", "LEAP_SECONDS",
           "LasWriter", "SCAN_FIELDS", "asprs_classes", "auto_offset", "check_output",
           "class_table", "count_points", "gps_time", "write_scan"]

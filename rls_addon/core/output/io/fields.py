"""Which point fields a cloud file may hold, and their on-disk types.

Files store what point-cloud tools expect, not our in-memory ``POINT_DTYPE``:
x, y, z, intensity as float32, ring uint16, time float64 (float32 on request),
label and instance uint32, ghost, return_index and num_returns uint8; ``range`` is
optional (float32).
PLY stores label and instance as int32 (``ply_records``). All on-disk types are
little-endian.
"""

import numpy as np

from ...choices import FIELDS
from ...errors import OutputError
from ...points import POINT_DTYPE

DEFAULT_FIELDS = ("x", "y", "z", "intensity", "ring", "time", "label", "instance", "ghost")
REQUIRED_FIELDS = ("x", "y", "z")

FILE_TYPES = {
    "x": "<f4",
    "y": "<f4",
    "z": "<f4",
    "range": "<f4",
    "intensity": "<f4",
    "ring": "<u2",
    "time": "<f8",
    "label": "<u4",
    "instance": "<u4",
    "ghost": "u1",
    "return_index": "u1",
    "num_returns": "u1",
}
TIME_DTYPES = ("float64", "float32")
assert set(FILE_TYPES) == set(REQUIRED_FIELDS) | set(FIELDS.ids)  # one list of fields

# PLY: the property types every tested reader keeps (tests/core/test_ply_readers.py;
# docs/formats.md). Open3D 0.20's tensor reader keeps only uchar/uint8, uint16, int/int32,
# float/float32 and double/float64 (it skips char, short, ushort, uint, uint32, ...), so
# 32-bit unsigned columns (label, instance) are stored as int32, and uint16 is spelled
# "uint16" (ply.py). PCD keeps FILE_TYPES.
_INT32_MAX = np.iinfo(np.int32).max


def resolve_fields(fields):
    """Validated field tuple in file order; x, y, z always first."""
    if fields is None:
        return DEFAULT_FIELDS
    if isinstance(fields, str):
        fields = [f.strip() for f in fields.split(",") if f.strip()]
    wanted = set(fields)
    for f in sorted(wanted - set(REQUIRED_FIELDS)):
        FIELDS.check(f)  # SettingsError naming the fields there are
    order = REQUIRED_FIELDS + tuple(f for f in FILE_TYPES if f not in REQUIRED_FIELDS)
    return tuple(f for f in order if f in REQUIRED_FIELDS or f in wanted)


def file_dtype(fields, time_dtype="float64"):
    """Packed little-endian structured dtype of the given fields."""
    if time_dtype not in TIME_DTYPES:
        raise OutputError(f"time_dtype must be one of {', '.join(TIME_DTYPES)}, got {time_dtype!r}")
    types = dict(FILE_TYPES, time="<f8" if time_dtype == "float64" else "<f4")
    return np.dtype([(f, types[f]) for f in fields])


def pack(points, fields, time_dtype="float64"):
    """Copy ``points`` into the on-disk record layout (one packed array)."""
    names = points.dtype.names or ()
    missing = [f for f in fields if f not in names]
    if missing:
        raise OutputError(f"points lack field(s) {', '.join(missing)} requested for output")
    # one structured cast of the fields' view (by position: both are in ``fields``
    # order), 3x faster than a copy per field on a Pandar64 frame
    return points[list(fields)].astype(file_dtype(fields, time_dtype))


def ply_records(records):
    """``records`` with the on-disk types of PLY: uint32 columns as int32.

    A uint32 column whose values all fit in int32 (every label and instance RLS makes:
    label ids are table ids, instance ids 31-bit hashes) is stored as int32, which every
    tested reader keeps; a column holding a value of 2**31 or more stays uint32 (exact,
    but Open3D's tensor reader skips it) rather than being wrapped. Other columns are
    unchanged. Returns ``records`` itself when nothing changes."""
    names = records.dtype.names or ()
    wide = [f for f in names if records.dtype[f] == np.dtype("<u4")
            and (len(records) == 0 or int(records[f].max()) <= _INT32_MAX)]
    if not wide:
        return records
    dt = np.dtype([(f, "<i4" if f in wide else records.dtype[f]) for f in names])
    out = np.empty(len(records), dtype=dt)
    for f in names:
        out[f] = records[f]
    return out


def unpack(records):
    """Map a structured array read from a file onto ``POINT_DTYPE``.

    Fields the file lacks are zero; fields we do not know are dropped.
    """
    out = np.zeros(len(records), dtype=POINT_DTYPE)
    for f in records.dtype.names or ():
        if f in POINT_DTYPE.names:
            col = records[f]
            if col.ndim > 1:
                col = col[:, 0]
            out[f] = col
    return out


# Coordinates this far from the origin (m) step by 2 mm or more in float32 (2**14 m):
# world-frame points there lose the precision a LiDAR's range noise keeps
FAR_FROM_ORIGIN_M = 2.0 ** 14


def float32_warning(points, fmt):
    """What a run says of world-frame ``points`` written as format ``fmt`` when they lie
    so far from the origin that the file's float32 x, y, z round them (a map's UTM
    coordinates: 0.5 m steps at 4.2e6 m), or None. LAS keeps them in integers about an
    offset, so it is spared."""
    if fmt == "las" or not len(points):
        return None
    reach = max(float(np.abs(points[c]).max()) for c in REQUIRED_FIELDS)
    if not reach >= FAR_FROM_ORIGIN_M:  # (NaN coordinates: not this warning's matter)
        return None
    step = float(np.spacing(np.float32(reach)))
    return (f"world-frame points reach {reach:,.0f} m from the origin, where the file's 32-bit "
            f"x, y, z step by {step * 1000:.0f} mm: write them in the sensor frame (the "
            "sidecar's pose maps them to the world in full precision) or as LAS, whose "
            "offset keeps millimetres")

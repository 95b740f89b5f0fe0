"""PLY (Stanford polygon format): vertices only, ascii or binary_little_endian."""

import numpy as np

from ...errors import InputError

from .fields import ply_records
from .text import ascii_rows, parse_rows

ENCODINGS = ("ascii", "binary_little_endian")
# Property type names. 16-bit unsigned is spelled "uint16": Open3D 0.20's tensor reader
# skips "ushort" but keeps "uint16" (tests/core/test_ply_readers.py); plyfile, PCL and
# rply-based readers know both spellings.
_NAME = {"f4": "float", "f8": "double", "u1": "uchar", "u2": "uint16", "u4": "uint",
         "i1": "char", "i2": "short", "i4": "int"}
_TYPE = {
    "char": "i1", "int8": "i1", "uchar": "u1", "uint8": "u1",
    "short": "i2", "int16": "i2", "ushort": "u2", "uint16": "u2",
    "int": "i4", "int32": "i4", "uint": "u4", "uint32": "u4",
    "float": "f4", "float32": "f4", "double": "f8", "float64": "f8",
}


def header(records, encoding):
    dt = records.dtype
    lines = ["ply", f"format {encoding} 1.0", "comment written by RLS (realistic LiDAR simulation)",
             f"element vertex {len(records)}"]
    for f in dt.names:
        lines.append(f"property {_NAME[dt[f].kind + str(dt[f].itemsize)]} {f}")
    lines.append("end_header")
    return ("\n".join(lines) + "\n").encode("ascii")


def encode(records, encoding):
    """Complete PLY file contents for a packed little-endian structured array; uint32
    columns whose values fit are stored as int32 (``fields.ply_records``)."""
    return b"".join(encode_parts(records, encoding))


def encode_parts(records, encoding):
    """The file's contents as buffers to write one after the other (a binary file's
    records as they are in memory, not copied behind the header)."""
    if encoding not in ENCODINGS:
        raise InputError(f"unknown PLY encoding {encoding!r}")
    records = ply_records(records)
    head = header(records, encoding)
    if encoding == "ascii":
        return [head, ascii_rows(records)]
    # packed little-endian by fields.pack
    return [head, memoryview(np.ascontiguousarray(records)).cast("B")]


def decode(blob):
    """Structured array of the ``vertex`` element's scalar properties."""
    end = blob.find(b"end_header")
    if not blob.startswith(b"ply") or end < 0:
        raise InputError("not a PLY file (no 'ply' magic or no end_header)")
    nl = blob.find(b"\n", end)
    body = nl + 1 if nl >= 0 else len(blob)
    lines = blob[:end].decode("ascii", "replace").splitlines()
    fmt, elements = None, []
    for line in lines[1:]:
        parts = line.split()
        if not parts or parts[0] in ("comment", "obj_info"):
            continue
        if parts[0] == "format":
            fmt = parts[1]
        elif parts[0] == "element":
            elements.append((parts[1], int(parts[2]), []))
        elif parts[0] == "property":
            if not elements:
                raise InputError("PLY property before any element")
            if parts[1] == "list":
                elements[-1][2].append((parts[4], None))
            else:
                if parts[1] not in _TYPE:
                    raise InputError(f"unknown PLY property type {parts[1]}")
                elements[-1][2].append((parts[2], _TYPE[parts[1]]))
    if fmt not in ("ascii", "binary_little_endian", "binary_big_endian"):
        raise InputError(f"unsupported PLY format {fmt!r}")
    if not elements or elements[0][0] != "vertex":
        raise InputError("PLY file does not start with a vertex element")
    _, n, props = elements[0]
    if any(t is None for _, t in props):
        raise InputError("PLY vertex element has list properties, which clouds do not use")
    order = "<" if fmt != "binary_big_endian" else ">"
    dt = np.dtype([(name, order + t if t[1] != "1" else t) for name, t in props])
    if fmt == "ascii":
        text = blob[body:].decode("ascii")
        rows = text.split("\n", n)[:n]
        return parse_rows("\n".join(rows), dt, n)
    need = dt.itemsize * n
    if len(blob) - body < need:
        raise InputError(f"PLY vertex data is {len(blob) - body} bytes, expected {need}")
    out = np.frombuffer(blob, dtype=dt, count=n, offset=body)
    return out.copy()

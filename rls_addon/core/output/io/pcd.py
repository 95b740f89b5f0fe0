"""PCD v0.7 (PCL's format): ascii, binary and binary_compressed.

Header fields: FIELDS, SIZE, TYPE (F float, U unsigned, I signed), COUNT,
WIDTH (points), HEIGHT 1 (unorganised), VIEWPOINT identity, POINTS, DATA.
``binary`` stores records back to back; ``binary_compressed`` stores two
uint32 (compressed size, uncompressed size) and an LZF stream of the data in
column order (all x, then all y, ...), as PCL writes it.
"""

import struct

import numpy as np

from ...errors import InputError

from . import lzf
from .text import ascii_rows, parse_rows

ENCODINGS = ("ascii", "binary", "binary_compressed")
_KIND = {"f": "F", "u": "U", "i": "I"}


def header(records, encoding):
    dt = records.dtype
    names = dt.names
    n = len(records)
    return (
        "# .PCD v0.7 - Point Cloud Data file format\n"
        "VERSION 0.7\n"
        f"FIELDS {' '.join(names)}\n"
        f"SIZE {' '.join(str(dt[f].itemsize) for f in names)}\n"
        f"TYPE {' '.join(_KIND[dt[f].kind] for f in names)}\n"
        f"COUNT {' '.join('1' for _ in names)}\n"
        f"WIDTH {n}\nHEIGHT 1\nVIEWPOINT 0 0 0 1 0 0 0\nPOINTS {n}\n"
        f"DATA {encoding}\n"
    ).encode("ascii")


def _columns(records):
    """Column-major bytes and LZF search segments (distances = multiples of the field size)."""
    parts, segments, pos = [], [], 0
    for f in records.dtype.names:
        col = np.ascontiguousarray(records[f]).tobytes()
        size = records.dtype[f].itemsize
        offs = sorted({1} | {size * k for k in (1, 2, 3, 4, 8, 16, 32, 64, 128) if size * k <= lzf.MAX_OFFSET})
        segments.append((pos, pos + len(col), offs))
        parts.append(col)
        pos += len(col)
    return b"".join(parts), segments


def encode(records, encoding):
    """Complete PCD file contents for a packed structured array."""
    return b"".join(encode_parts(records, encoding))


def encode_parts(records, encoding):
    """The file's contents as buffers to write one after the other (the records of a
    binary file as they are in memory, not copied behind the header)."""
    if encoding not in ENCODINGS:
        raise InputError(f"unknown PCD encoding {encoding!r}")
    head = header(records, encoding)
    if encoding == "ascii":
        return [head, ascii_rows(records)]
    if encoding == "binary":
        return [head, memoryview(np.ascontiguousarray(records)).cast("B")]
    raw, segments = _columns(records)
    packed = lzf.compress(raw, segments)
    return [head, struct.pack("<II", len(packed), len(raw)), packed]


HEADER_KEYS = (b"VERSION", b"FIELDS", b"SIZE", b"TYPE", b"COUNT", b"WIDTH", b"HEIGHT",
               b"VIEWPOINT", b"POINTS", b"DATA")


def recognise(blob):
    """Whether ``blob`` starts as a PCD file: comment lines, then a header key."""
    pos = 0
    while True:
        end = blob.find(b"\n", pos)
        line = blob[pos:len(blob) if end < 0 else end].strip()
        if line and not line.startswith(b"#"):
            return line.split()[0].upper() in HEADER_KEYS
        if end < 0:
            return False
        pos = end + 1


def _parse_header(blob):
    meta, pos = {}, 0
    while True:
        end = blob.find(b"\n", pos)
        if end < 0:
            raise InputError("PCD header has no DATA line")
        line = blob[pos:end].decode("ascii", "replace").strip()
        pos = end + 1
        if not line or line.startswith("#"):
            continue
        key, _, rest = line.partition(" ")
        meta[key.upper()] = rest.split()
        if key.upper() == "DATA":
            return meta, pos


def _dtype(meta):
    names = meta.get("FIELDS")
    if not names:
        raise InputError("PCD header has no FIELDS")
    sizes = [int(v) for v in meta.get("SIZE", [])]
    types = meta.get("TYPE", [])
    counts = [int(v) for v in meta.get("COUNT", ["1"] * len(names))]
    if not (len(sizes) == len(types) == len(counts) == len(names)):
        raise InputError("PCD header FIELDS, SIZE, TYPE and COUNT differ in length")
    fields, seen = [], {}
    for name, size, typ, count in zip(names, sizes, types, counts):
        kind = {"F": "f", "U": "u", "I": "i"}.get(typ.upper())
        if kind is None:
            raise InputError(f"PCD field {name} has unknown TYPE {typ}")
        if name == "_":  # PCL padding
            seen[name] = seen.get(name, 0) + 1
            name = f"_pad{seen['_']}"
        base = np.dtype(f"<{kind}{size}") if size > 1 else np.dtype(f"{kind}1")
        fields.append((name, base, (count,)) if count > 1 else (name, base))
    return np.dtype(fields)


def decode(blob):
    """Structured array (the file's own field types) from PCD file contents."""
    meta, pos = _parse_header(blob)
    dt = _dtype(meta)
    if "POINTS" in meta:
        n = int(meta["POINTS"][0])
    else:
        n = int(meta.get("WIDTH", ["0"])[0]) * int(meta.get("HEIGHT", ["1"])[0])
    encoding = meta["DATA"][0].lower() if meta["DATA"] else ""
    if encoding == "ascii":
        return parse_rows(blob[pos:].decode("ascii"), dt, n)
    if encoding == "binary":
        need = dt.itemsize * n
        if len(blob) - pos < need:
            raise InputError(f"PCD binary data is {len(blob) - pos} bytes, expected {need}")
        return np.frombuffer(blob, dtype=dt, count=n, offset=pos).copy()
    if encoding == "binary_compressed":
        if n == 0 and len(blob) - pos < 8:
            return np.empty(0, dtype=dt)
        csize, usize = struct.unpack_from("<II", blob, pos)
        if usize != dt.itemsize * n:
            raise InputError(f"PCD compressed data holds {usize} bytes, expected {dt.itemsize * n}")
        raw = lzf.decompress(blob[pos + 8:pos + 8 + csize], usize)
        out = np.empty(n, dtype=dt)
        off = 0
        for f in dt.names:
            sub = dt[f]
            size = sub.itemsize * n
            out[f] = np.frombuffer(raw, dtype=sub.base, count=n * max(1, int(np.prod(sub.shape))), offset=off).reshape(out[f].shape)
            off += size
        return out
    raise InputError(f"unknown PCD DATA encoding {encoding!r}")

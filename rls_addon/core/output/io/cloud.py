"""Write and read whole point-cloud files in the record formats of ``formats.FORMATS``
(PCD, PLY and any added with ``formats.record_format``)."""

import pathlib
import struct

from ...errors import InputError, SettingsError
from .atomic import atomic_write_bytes, parts_writer
from .fields import pack, resolve_fields, unpack
from .formats import FORMATS, readable_format


def encode_cloud(points, fmt="pcd_binary", fields=None, time_dtype="float64"):
    """The bytes of a cloud file (no file system access)."""
    return encode_records(pack(points, resolve_fields(fields), time_dtype), fmt)


def encode_records(records, fmt):
    """The bytes of a file of packed records (any fields, e.g. a driver's point type) in
    the record format ``fmt``."""
    return b"".join(record_parts(records, fmt))


def record_parts(records, fmt):
    """``encode_records`` as buffers to write one after another (no joined copy)."""
    entry = FORMATS.get(fmt)
    if entry.encode is None:
        raise SettingsError(f"{fmt} files are written by the scan run's writers "
                            "(io.writer), not encode_records")
    return entry.encode(records)


def write_cloud(path, points, fmt="pcd_binary", fields=None, overwrite=False, time_dtype="float64"):
    """Write ``points`` to ``path`` atomically; returns the path.

    ``fields``: names to store (x, y, z are always stored); default all of
    x y z intensity ring time label instance ghost. ``time_dtype``:
    "float64" (default) or "float32". The path is used as given; use
    ``output_path`` to build one with the right extension.
    """
    path = pathlib.Path(path)
    parts = record_parts(pack(points, resolve_fields(fields), time_dtype), fmt)
    return atomic_write_bytes(path, parts_writer(parts), overwrite=overwrite)


def read_records(path):
    """The file's records with their own field types, in the format its contents show
    (``formats.readable_format``), whatever its name."""
    path = pathlib.Path(path)
    try:
        blob = path.read_bytes()
    except OSError as exc:
        raise InputError(f"cannot read point cloud {path}: {exc.strerror or exc}") from None
    fmt = readable_format(blob, path)
    try:
        return fmt.decode(blob)
    except (InputError, ValueError, IndexError, struct.error) as exc:
        kind = fmt.extension.lstrip(".").upper() or fmt.label
        raise InputError(f"{path} is not a readable {kind} point cloud: {exc}") from None


def read_cloud(path):
    """Read a cloud file into a ``POINT_DTYPE`` array.

    Fields missing from the file (e.g. ``range``) are zero.
    """
    return unpack(read_records(path))


__all__ = ["encode_cloud", "encode_records", "read_cloud", "read_records", "record_parts",
           "write_cloud"]

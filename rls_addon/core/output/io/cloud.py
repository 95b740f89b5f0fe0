"""Write and read whole point-cloud files in any of ``FORMATS``."""

import pathlib

from ...errors import InputError, SettingsError
from . import pcd, ply
from .atomic import atomic_write_bytes
from .fields import FORMAT_EXT, check_format, pack, resolve_fields, unpack

_ENCODING = {
    "pcd_ascii": (pcd, "ascii"),
    "pcd_binary": (pcd, "binary"),
    "pcd_binary_compressed": (pcd, "binary_compressed"),
    "ply_ascii": (ply, "ascii"),
    "ply_binary": (ply, "binary_little_endian"),
}


def encode_cloud(points, fmt="pcd_binary", fields=None, time_dtype="float64"):
    """The bytes of a cloud file (no file system access)."""
    return encode_records(pack(points, resolve_fields(fields), time_dtype), fmt)


def encode_records(records, fmt):
    """The bytes of a PCD or PLY file of packed records (any fields, e.g. a driver's
    point type)."""
    return b"".join(record_parts(records, fmt))


def record_parts(records, fmt):
    """``encode_records`` as buffers to write one after another (no joined copy)."""
    check_format(fmt)
    if fmt not in _ENCODING:
        raise SettingsError(f"{fmt} files are written by the scan run's writers "
                            "(io.writer), not encode_records")
    module, encoding = _ENCODING[fmt]
    return module.encode_parts(records, encoding)


def parts_writer(parts):
    """A writer of ``parts`` for ``atomic_write_bytes``."""
    def write(fh):
        for part in parts:
            fh.write(part)
    return write


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
    """The file's records with their own field types (PCD or PLY, by content)."""
    path = pathlib.Path(path)
    try:
        blob = path.read_bytes()
    except OSError as exc:
        raise InputError(f"cannot read point cloud {path}: {exc.strerror or exc}") from None
    try:
        if blob.startswith(b"ply"):
            return ply.decode(blob)
        return pcd.decode(blob)
    except (InputError, ValueError, UnicodeDecodeError, IndexError) as exc:
        raise InputError(f"{path} is not a readable PCD/PLY point cloud: {exc}") from None


def read_cloud(path):
    """Read a PCD or PLY cloud into a ``POINT_DTYPE`` array.

    Fields missing from the file (e.g. ``range``) are zero.
    """
    return unpack(read_records(path))


__all__ = ["FORMAT_EXT", "encode_cloud", "read_cloud", "read_records", "write_cloud"]

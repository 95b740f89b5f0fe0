"""The output formats, one ``OutputFormat`` entry each: what the scan run's writers,
the cloud readers, ``rls scan --format`` and the LiDAR panel's Format list know of a
format, in one place (``FORMATS``).

A format is one of three kinds:

* a file of packed point records per scan (PCD, PLY): ``record_format(...)`` makes the
  entry from an ``encode(records) -> byte parts`` and, to read it back, a
  ``decode(bytes) -> records`` and a ``recognise(bytes) -> bool``; the output's fields
  or point type choose the records;
* a file per scan that writes itself (LAS): ``write(cloud) -> fields written`` and
  ``count(path) -> points`` (resume);
* one output for a whole run (ROS 2 bags): ``run_writer(jobs, scene_name, fps,
  first_frame, overwrite, resume)``, the run's ``Writer``.

Adding a format is one module (e.g. ``ply.py``) and one entry:
``FORMATS.add(record_format("xyz", "XYZ", "x y z per line", ".xyz", encode, decode,
recognise))``; ``FORMATS.remove("xyz")`` takes it out again.
"""

import functools
import struct
from dataclasses import dataclass
from pathlib import Path
from typing import Callable

from ...choices import Registry
from ...errors import InputError
from . import bag_writer, las, pcd, ply
from .atomic import atomic_write_bytes, parts_writer
from .fields import pack, resolve_fields
from .point_types import to_point_type


@dataclass(frozen=True)
class Cloud:
    """One scan's cloud as a format writes it."""

    path: Path      # where (the output's template with the format's extension)
    sensor: str
    points: object  # (N,) POINT_DTYPE in the output's frame (``info["frame_space"]``)
    info: dict      # the sidecar's facts: timestamp_s, poses, channel_elevations_deg, ...
    output: object  # the sensor's ``scan.settings.OutputSettings``
    overwrite: bool
    sensors: tuple = ()  # every sensor of the run, in order


@dataclass(frozen=True)
class OutputFormat:
    """One output format (see the module's docstring for the three kinds).

    id, label, description  the setting's value, the UI's name, one line of help
    extension               of its files ('.pcd'); '' for a run's output (a folder)
    write, count            a file per scan: write one (atomically), count a file's points
    encode, decode          packed records to file bytes (in parts) and back; with
    recognise               encode, the output's fields and point type apply; decode and
                            recognise (does a file's start look like this format)
                            let ``cloud.read_records`` read it
    check                   ``check(output)``: before the first scan, whether this
                            output can be written (a library present, settings valid)
    run_writer              a whole run in one output: makes the run's writer
    frame_space             the coordinate frame its clouds must be in, or None
    """

    id: str
    label: str
    description: str
    extension: str
    write: Callable = None
    count: Callable = None
    encode: Callable = None
    decode: Callable = None
    recognise: Callable = None
    check: Callable = None
    run_writer: Callable = None
    frame_space: str = None


def record_format(id, label, description, extension, encode, decode=None, recognise=None):
    """The entry of a file format of packed point records: ``encode(records)`` gives the
    file's contents as byte parts; ``decode(blob)`` and ``recognise(blob)`` read it back."""
    count = None if decode is None else functools.partial(count_records, decode=decode)
    return OutputFormat(id, label, description, extension,
                        write=functools.partial(write_records, encode=encode), count=count,
                        encode=encode, decode=decode, recognise=recognise)


def cloud_records(cloud):
    """The records a record format stores of ``cloud``: its output's fields (point type
    'rls'), or a vendor driver's point type."""
    out = cloud.output
    if out.point_type != "rls":
        return to_point_type(cloud.points, out.point_type,
                             start_time_s=cloud.info.get("timestamp_s", 0.0),
                             channel_elevations_deg=cloud.info.get("channel_elevations_deg"))
    return pack(cloud.points, resolve_fields(out.fields))


def write_records(cloud, encode):
    """Write ``cloud`` as a file of records (atomically); returns the fields written."""
    records = cloud_records(cloud)
    atomic_write_bytes(cloud.path, parts_writer(encode(records)), overwrite=cloud.overwrite)
    return list(records.dtype.names)


def count_records(path, decode):
    """Points in a file of records: all of it read back (``InputError`` when it does
    not read)."""
    try:
        return len(decode(Path(path).read_bytes()))
    except (ValueError, IndexError, struct.error) as exc:
        raise InputError(f"{path} does not read back: {exc}") from None


def _is_ply(blob):
    return blob.startswith(b"ply")


FORMATS = Registry("cloud format", [
    record_format("pcd_binary", "PCD binary", "PCD v0.7, binary", ".pcd",
                  functools.partial(pcd.encode_parts, encoding="binary"), pcd.decode,
                  pcd.recognise),
    record_format("pcd_binary_compressed", "PCD binary compressed",
                  "PCD v0.7, LZF-compressed binary", ".pcd",
                  functools.partial(pcd.encode_parts, encoding="binary_compressed"),
                  pcd.decode, pcd.recognise),
    record_format("pcd_ascii", "PCD ASCII", "PCD v0.7, text", ".pcd",
                  functools.partial(pcd.encode_parts, encoding="ascii"), pcd.decode,
                  pcd.recognise),
    record_format("ply_binary", "PLY binary", "PLY, binary little endian", ".ply",
                  functools.partial(ply.encode_parts, encoding="binary_little_endian"),
                  ply.decode, _is_ply),
    record_format("ply_ascii", "PLY ASCII", "PLY, text", ".ply",
                  functools.partial(ply.encode_parts, encoding="ascii"), ply.decode, _is_ply),
    OutputFormat("las", "LAS 1.4", "ASPRS LAS 1.4 in world coordinates, GPS time, ASPRS "
                 "classes, ring/label/instance/ghost as extra bytes (needs laspy)", ".las",
                 write=las.write_scan, count=las.count_points, check=las.check_output),
    OutputFormat("mcap", "ROS 2 bag (MCAP)", "One rosbag2 per run: PointCloud2 on "
                 "/<sensor>/points, /tf and /tf_static (needs rosbags)", "",
                 run_writer=bag_writer.run_writer, frame_space="sensor"),
])


def readable_format(blob, where):
    """The first format that recognises ``blob`` (a file's contents) and reads it back;
    ``InputError`` naming ``where`` and the formats read when none does."""
    readable = [f for f in FORMATS if f.decode is not None and f.recognise is not None]
    for fmt in readable:
        if fmt.recognise(blob):
            return fmt
    kinds = ", ".join(dict.fromkeys(f.extension for f in readable))
    first = bytes(blob[:200]).lstrip().split(b"\n")[0][:40]
    seen = f"it starts with {first!r}, not a PCD header or 'ply'" if first else \
        "it holds nothing but white space" if len(blob) else "it is empty"
    raise InputError(f"{where} is not a point cloud file RLS reads ({kinds}): {seen}")


__all__ = ["Cloud", "FORMATS", "OutputFormat", "cloud_records", "readable_format",
           "record_format"]

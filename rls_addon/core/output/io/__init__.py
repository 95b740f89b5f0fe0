"""Point-cloud files: the output formats (``formats.FORMATS``: PCD ascii, binary,
binary_compressed; PLY ascii, binary_little_endian; LAS; ROS 2 bags) and the scan run's
writers; atomic writes; output file names from templates; JSON sidecars.
"""

from .atomic import atomic_write_bytes, ensure_directory, writable_folder
from .cloud import encode_cloud, read_cloud, read_records, write_cloud
from .fields import DEFAULT_FIELDS, FILE_TYPES
from .formats import FORMATS
from .names import sanitize_name
from .paths import output_path
from .sidecar import read_sidecar, sidecar_path, write_sidecar

__all__ = [
    "DEFAULT_FIELDS",
    "FILE_TYPES",
    "FORMATS",
    "atomic_write_bytes",
    "encode_cloud",
    "ensure_directory",
    "output_path",
    "read_cloud",
    "read_records",
    "read_sidecar",
    "sanitize_name",
    "sidecar_path",
    "write_cloud",
    "write_sidecar",
    "writable_folder",
]

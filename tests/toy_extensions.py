"""A toy device family and a toy output format, added through the registries alone
(``FAMILIES.add``, ``FORMATS.add``) as a developer adds a real one: the test of issue 41's
"adding a family or a format is one module and one entry". Each tier's test uses them
inside ``registered()``, which takes them out again.

toy_fan    a fan of ``rays`` rays across ``fov_deg`` of azimuth, centred on +X, at one
           elevation: from a height h over flat ground at elevation e < 0, every ray
           meets the ground at range h / sin(-e)
toy_text   a text file: a first line 'rls-toy-text <field> ...', then one line per
           point of its fields' values (17 significant digits: float64 exactly)
"""

import io
from contextlib import contextmanager

import numpy as np

from rls_addon.core.device import schema as sch
from rls_addon.core.device.families import FAMILIES, Family
from rls_addon.core.device.patterns.base import ScanPattern, directions_from_angles
from rls_addon.core.errors import InputError
from rls_addon.core.output.io.formats import FORMATS, record_format

FAMILY_ID, FORMAT_ID, EXTENSION = "toy_fan", "toy_text", ".toy"
MAGIC = b"rls-toy-text"


# ---- the family: its module would hold these three -------------------------------------

SCAN_KEYS = frozenset({"rays", "fov_deg", "elevation_deg"})


def check(scan, where, frequency_hz, base_dir):
    rays = sch.integer(scan, "rays", where, 1, 100_000)
    sch.num(scan, "fov_deg", where, 0.0, 360.0)
    sch.num(scan, "elevation_deg", where, -90.0, 90.0, default=0.0)
    return rays, {}


def build(preset, frame):
    s = preset.scan
    n = int(s["rays"])
    half = float(s["fov_deg"]) / 2.0
    az = np.deg2rad(np.linspace(-half, half, n))
    el = np.full(n, np.deg2rad(float(s.get("elevation_deg", 0.0))))
    times = np.arange(n) * (preset.period / n)
    return ScanPattern(directions_from_angles(az, el), times, np.zeros(n, np.uint16),
                       preset.period)


# ---- the format: its module would hold these three -------------------------------------

def encode(records):
    names = records.dtype.names
    body = io.StringIO()
    columns = np.column_stack([records[f].astype(np.float64) for f in names]) \
        if len(records) else np.empty((0, len(names)))
    np.savetxt(body, columns, fmt="%.17g")
    return [MAGIC + b" " + " ".join(names).encode("ascii") + b"\n",
            body.getvalue().encode("ascii")]


def decode(blob):
    first, _, rest = blob.partition(b"\n")
    names = first.decode("ascii").split()[1:]
    rows = np.loadtxt(io.BytesIO(rest), ndmin=2) if rest.strip() else np.empty((0, len(names)))
    if rows.shape[1] != len(names):
        raise InputError(f"{rows.shape[1]} values a row for {len(names)} fields")
    out = np.empty(len(rows), dtype=[(n, "<f8") for n in names])
    for i, n in enumerate(names):
        out[n] = rows[:, i]
    return out


def recognise(blob):
    return blob.startswith(MAGIC + b" ")


# ---- the two entries -------------------------------------------------------------------

FAMILY = Family(FAMILY_ID, "Toy Fan", "LIGHT_AREA", "A fan of rays at one elevation (a test)",
                SCAN_KEYS, check, build)
FORMAT = record_format(FORMAT_ID, "Toy text", "One line of values per point (a test)",
                       EXTENSION, encode, decode, recognise)


@contextmanager
def registered():
    """The toy family and format in the registries for the block, taken out after."""
    FAMILIES.add(FAMILY)
    try:
        FORMATS.add(FORMAT)
        try:
            yield
        finally:
            FORMATS.remove(FORMAT_ID)
    finally:
        FAMILIES.remove(FAMILY_ID)


PRESET_TOML = """id = "toy_fan_64"
name = "Toy Fan 64"
family = "toy_fan"
source = "tests/toy_extensions.py"
frequency_hz = 10.0

[range]
min_m = 0.1
max_m = 50.0

[scan]
rays = 64
fov_deg = 90.0
elevation_deg = -30.0
"""


def write_preset(folder):
    """A user preset of the toy family in ``folder``; returns its path."""
    folder.mkdir(parents=True, exist_ok=True)
    path = folder / "toy_fan_64.toml"
    path.write_text(PRESET_TOML, encoding="utf-8")
    return path

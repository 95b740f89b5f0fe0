"""A real unit's calibration file, read as data (never executed).

Five formats, each as its vendor's drivers read it (sources beside each reader):

- Hesai angle-correction CSV: header ``Channel,Elevation,Azimuth`` (or ``Laser id`` /
  ``LaserID``), one row per channel, degrees, channels 1-based (HesaiLidar_SDK_2.0
  ``correction/angle_correction/*.csv``, tier4/nebula ``calibration/Pandar*.csv``).
- Velodyne calibration YAML: ``lasers:`` with ``laser_id``, ``rot_correction`` and
  ``vert_correction`` (radians), optional ``vert_offset_correction`` and
  ``horiz_offset_correction`` (metres; 0 when absent, as ros-drivers/velodyne
  ``calibration.cc`` reads them).
- Velodyne ``db.xml``: the boost-serialised calibration Velodyne ships (``DB/points_``
  items with ``id_``, ``rotCorrection_``, ``vertCorrection_`` in degrees and
  ``vertOffsetCorrection_``, ``horizOffsetCorrection_`` in centimetres; ``DB/enabled_``
  flags), as ros-drivers/velodyne ``scripts/gen_calibration.py`` converts it.
- Ouster sensor metadata JSON: ``beam_altitude_angles``, ``beam_azimuth_angles`` (degrees)
  and the beam origin (``beam_to_lidar_transform`` or ``lidar_origin_to_beam_origin_mm``),
  flat (firmware 1.x/2.0 "legacy") or nested under ``beam_intrinsics`` (2.x, 3.x), as
  ouster-sdk ``ouster_core/src/metadata.cpp`` reads them.
- RoboSense ``angle.csv``: no header, one row per channel in file order: vertical angle
  and (except 16-laser units) horizontal offset, degrees (RoboSense-LiDAR/ros_rslidar
  ``rslidar_pointcloud/data/*/angle.csv``, tier4/nebula ``calibration/robosense``).

``read_calibration`` returns a ``UnitCalibration``: angles as the vendor gives them (the
convention of ``angle_tables.AZIMUTH_CONVENTIONS``) and, where the file gives beam origins,
each beam's origin in the head frame (metres; +X the head's direction, +Y left, +Z up).
Every error names the file, and the line where there is one.
"""

import hashlib
import json
import math
import re
from dataclasses import dataclass
from pathlib import Path

from ..errors import PresetError

MAX_CALIBRATION_BYTES = 2_000_000
MAX_CHANNELS = 1024

FORMATS = {
    "hesai-csv": "Hesai angle-correction CSV (header 'Channel,Elevation,Azimuth' or "
                 "'Laser id,Elevation,Azimuth')",
    "velodyne-yaml": "Velodyne calibration YAML ('lasers:' with laser_id, rot_correction, "
                     "vert_correction)",
    "velodyne-xml": "Velodyne db.xml (DB/points_ with id_, rotCorrection_, vertCorrection_)",
    "ouster-json": "Ouster sensor metadata JSON (beam_altitude_angles, beam_azimuth_angles)",
    "robosense-csv": "RoboSense angle.csv (no header; vertical[,horizontal] degrees per row)",
}
VENDOR = {"hesai-csv": "hesai", "velodyne-yaml": "velodyne", "velodyne-xml": "velodyne",
          "ouster-json": "ouster", "robosense-csv": "robosense"}

# ouster-sdk ouster_core/src/sensor_info.cpp default_lidar_origin_to_beam_origin: the
# origin the SDK assumes when a (firmware 1.12-1.13) metadata file gives none.
OUSTER_DEFAULT_ORIGIN_MM = (("OS-0-", 27.67), ("OS-1-", 15.806), ("OS-2-", 13.762))
OUSTER_GEN1_ORIGIN_MM = 12.163


@dataclass(frozen=True)
class UnitCalibration:
    format: str                 # a key of FORMATS
    channel_ids: tuple          # as the file numbers them, in table order
    elevations_deg: tuple
    azimuth_offsets_deg: tuple  # the vendor's values (its convention, VENDOR[format])
    origins_m: tuple = None     # ((x, y, z) per channel, head frame) or None: none given
    note: str = ""              # what else the file said that RLS uses or leaves alone
    file_name: str = ""
    sha256: str = ""

    @property
    def vendor(self):
        return VENDOR[self.format]


def accepted_formats():
    return "; ".join(FORMATS.values())


def _fail(where, line, msg):
    at = f"{where} line {line}" if line else where
    raise PresetError(f"{at}: {msg}")


def _number(text, where, line, what):
    try:
        v = float(text)
    except (TypeError, ValueError):
        _fail(where, line, f"{what} must be a number, got '{str(text).strip()}'")
    if isinstance(text, bool):
        _fail(where, line, f"{what} must be a number, got {text}")
    if not math.isfinite(v):
        _fail(where, line, f"{what} must be finite, got {v}")
    return v


def _angles(where, rows):
    """Check (line, channel id, elevation, azimuth, origin) rows: angles in range, ids
    unique. Returns the rows sorted by channel id."""
    if not rows:
        _fail(where, None, "no channels found")
    if len(rows) > MAX_CHANNELS:
        _fail(where, None, f"more than {MAX_CHANNELS} channels")
    seen = {}
    for line, cid, el, az, _o in rows:
        if cid in seen:
            _fail(where, line, f"duplicate channel id {cid} (also on line {seen[cid]})")
        seen[cid] = line
        if not -90.0 <= el <= 90.0:
            _fail(where, line, f"elevation {el} deg of channel {cid} is outside -90..90")
        if not -360.0 <= az <= 360.0:
            _fail(where, line, f"azimuth offset {az} deg of channel {cid} is outside -360..360")
    return sorted(rows, key=lambda r: r[1])


def _consecutive(where, rows, first):
    ids = [r[1] for r in rows]
    want = list(range(first, first + len(ids)))
    if ids != want:
        missing = sorted(set(want) - set(ids))
        line = next((r[0] for r in rows if r[1] not in want), None)
        _fail(where, line, f"channel ids must run {first}..{first + len(ids) - 1}"
                           + (f"; {missing[0]} is missing" if missing else ""))


def _result(fmt, rows, where, note, origins_given):
    rows = _angles(where, rows)
    origins = None
    if origins_given:
        origins = tuple(r[4] for r in rows)
        for line, cid, _e, _a, o in rows:
            if any(abs(v) > 1.0 for v in o):
                _fail(where, line, f"beam origin {o} m of channel {cid} is more than 1 m off")
        if not any(any(v != 0.0 for v in o) for o in origins):
            origins = None  # all zero: the beams leave from the origin
    return UnitCalibration(fmt, tuple(r[1] for r in rows), tuple(r[2] for r in rows),
                           tuple(r[3] for r in rows), origins, note)


# ---- Hesai --------------------------------------------------------------------------------

def _norm(cell):
    return re.sub(r"[\s_]", "", cell.strip().lower())


def _hesai(lines, where):
    """Hesai angle-correction CSV. The SDKs read the first three columns (channel,
    elevation, azimuth offset added to the block azimuth); see angle_tables for the sign."""
    header_line, header = lines[0]
    cells = [_norm(c) for c in header.split(",")]
    if len(cells) < 3 or cells[0] not in ("channel", "laserid") or cells[1:3] != \
            ["elevation", "azimuth"]:
        _fail(where, header_line, "header must be 'Channel,Elevation,Azimuth' (or 'Laser id,"
                                  f"Elevation,Azimuth'), got '{header.strip()}'")
    rows = []
    for line, text in lines[1:]:
        c = [x.strip() for x in text.split(",")]
        if len(c) < 3 or not all(c[:3]):
            _fail(where, line, f"expected channel, elevation and azimuth, got '{text.strip()}'")
        cid = _number(c[0], where, line, "channel id")
        if cid != int(cid) or cid < 0:
            _fail(where, line, f"channel id must be a whole number, got '{c[0]}'")
        rows.append((line, int(cid), _number(c[1], where, line, "elevation"),
                     _number(c[2], where, line, "azimuth"), None))
    rows_sorted = _angles(where, rows)
    _consecutive(where, rows_sorted, 1)
    return _result("hesai-csv", rows, where, "channels 1-based as in the file", False)


# ---- RoboSense ----------------------------------------------------------------------------

def _robosense(lines, where):
    """RoboSense angle.csv: row i is channel i (1-based) in file order; one column
    (vertical angle; 16-laser units, whose horizontal offset the driver sets to 0) or two
    (vertical, horizontal offset added to the block azimuth)."""
    ncol = len(lines[0][1].split(","))
    rows = []
    for k, (line, text) in enumerate(lines, start=1):
        c = [x.strip() for x in text.split(",")]
        if len(c) != ncol:
            _fail(where, line, f"expected {ncol} column{'s' if ncol > 1 else ''} like the "
                               f"first row, got {len(c)}")
        el = _number(c[0], where, line, "vertical angle")
        az = _number(c[1], where, line, "horizontal angle") if ncol == 2 else 0.0
        rows.append((line, k, el, az, None))
    note = "channels 1-based in file order" + ("; no horizontal column (0)" if ncol == 1 else "")
    return _result("robosense-csv", rows, where, note, False)


# ---- Velodyne -----------------------------------------------------------------------------

def _velodyne_origin(v_m, h_m, el_deg, rot_deg):
    """A laser's origin in the head frame from its vertical and horizontal offsets:
    ros-drivers/velodyne velodyne_pointcloud/src/lib/rawdata.cc puts a point at
    xy = d cos(w) - v sin(w); x' = xy sin(b) - h cos(b); y' = xy cos(b) + h sin(b);
    z = d sin(w) + v cos(w), then (x, y) = (y', -x') (b: encoder - rot_correction,
    clockwise; w: vert_correction). That is d along the beam from
    Rz(a) (-v sin(w), h, v cos(w)), a = -b the beam's counter-clockwise azimuth; in the
    head frame (a less the head angle = +rot_correction) the origin is turned by
    rot_correction only."""
    w, r = math.radians(el_deg), math.radians(rot_deg)
    ox, oy, oz = -v_m * math.sin(w), h_m, v_m * math.cos(w)
    return (ox * math.cos(r) - oy * math.sin(r), ox * math.sin(r) + oy * math.cos(r), oz)


def _velodyne_yaml(text, where):
    try:
        import yaml
    except ImportError:
        raise PresetError(f"{where}: reading a Velodyne YAML calibration needs PyYAML "
                          f"(pip install pyyaml)") from None
    loader = yaml.SafeLoader(text)
    try:
        node = loader.get_single_node()
        data = loader.construct_document(node) if node is not None else None
    except yaml.YAMLError as exc:
        mark = getattr(exc, "problem_mark", None)
        _fail(where, mark.line + 1 if mark else None, f"not valid YAML ({getattr(exc, 'problem', exc)})")
    except RecursionError:
        _fail(where, None, "not a readable YAML file (nested too deeply)")
    except ValueError as exc:  # a value the constructors refuse (an integer of 5000 digits)
        _fail(where, None, f"not a readable YAML file ({str(exc).split(';')[0]})")
    finally:
        loader.dispose()
    if not isinstance(data, dict) or not isinstance(data.get("lasers"), list):
        _fail(where, None, "not a Velodyne calibration YAML (no 'lasers:' list); accepted: "
                           + accepted_formats())
    lines = []
    for k, v in node.value:
        if getattr(k, "value", None) == "lasers" and hasattr(v, "value"):
            lines = [item.start_mark.line + 1 for item in v.value]
    rows = []
    for i, laser in enumerate(data["lasers"]):
        line = lines[i] if i < len(lines) else None
        if not isinstance(laser, dict):
            _fail(where, line, f"laser {i} must be a mapping of keys")
        for key in ("laser_id", "rot_correction", "vert_correction"):
            if key not in laser:
                _fail(where, line, f"laser {i} has no '{key}'")
        lid = laser["laser_id"]
        if isinstance(lid, bool) or not isinstance(lid, int) or lid < 0:
            _fail(where, line, f"laser {i}: laser_id must be a whole number, got {lid!r}")
        el = math.degrees(_number(laser["vert_correction"], where, line, "vert_correction"))
        rot = math.degrees(_number(laser["rot_correction"], where, line, "rot_correction"))
        v = _number(laser.get("vert_offset_correction", 0.0), where, line, "vert_offset_correction")
        h = _number(laser.get("horiz_offset_correction", 0.0), where, line,
                    "horiz_offset_correction")
        rows.append((line, lid, el, rot, _velodyne_origin(v, h, el, rot)))
    n = data.get("num_lasers")
    if n is not None and n != len(rows):
        _fail(where, None, f"num_lasers is {n} but {len(rows)} lasers are listed")
    _consecutive(where, _angles(where, rows), 0)
    return _result("velodyne-yaml", rows, where,
                   "laser_id order; rot/vert_correction radians -> degrees; distance, "
                   "focal and intensity corrections not used", True)


def _velodyne_xml(text, where):
    import xml.etree.ElementTree as ET

    # Velodyne's files open with a bare '<!DOCTYPE boost_serialization>'; anything that
    # declares entities is refused (no expansion of any kind).
    if re.search(r"<!ENTITY|<!DOCTYPE[^>]*\[", text, re.IGNORECASE):
        _fail(where, None, "XML with entity declarations or an internal DTD is refused")
    try:
        root = ET.fromstring(text)
    except ET.ParseError as exc:
        _fail(where, exc.position[0] if hasattr(exc, "position") else None,
              f"not valid XML ({exc})")
    db = root.find("DB") if root.tag != "DB" else root
    points = None if db is None else db.find("points_")
    if points is None:
        _fail(where, None, "not a Velodyne db.xml (no DB/points_); accepted: " + accepted_formats())
    enabled = None
    en = db.find("enabled_")
    if en is not None:
        enabled = [(x.text or "").strip() != "0" for x in en if x.tag == "item"]
    px_lines = [text.count("\n", 0, m.start()) + 1 for m in re.finditer(r"<px[\s>]", text)]
    rows = []
    items = [it for it in points if it.tag == "item"]
    for i, item in enumerate(items):
        line = px_lines[i] if i < len(px_lines) else None
        px = item.find("px")
        if px is None:
            _fail(where, line, f"points_ item {i} has no px")

        def field(tag, default=None):
            e = px.find(tag)
            if e is None:
                if default is None:
                    _fail(where, line, f"points_ item {i} has no {tag}")
                return default
            return _number(e.text, where, line, tag)

        lid = field("id_")
        if lid != int(lid) or lid < 0:
            _fail(where, line, f"id_ must be a whole number, got {lid}")
        lid = int(lid)
        if enabled is not None and lid < len(enabled) and not enabled[lid]:
            continue  # ros gen_calibration.py skips lasers that are not enabled
        el, rot = field("vertCorrection_"), field("rotCorrection_")
        v = field("vertOffsetCorrection_", 0.0) * 0.01  # cm -> m (gen_calibration.py)
        h = field("horizOffsetCorrection_", 0.0) * 0.01
        rows.append((line, lid, el, rot, _velodyne_origin(v, h, el, rot)))
    _consecutive(where, _angles(where, rows), 0)
    return _result("velodyne-xml", rows, where,
                   "enabled lasers in id_ order; degrees; offsets cm -> m; distance, focal "
                   "and intensity corrections not used", True)


# ---- Ouster -------------------------------------------------------------------------------

def _ouster(text, where):
    try:
        data = json.loads(text)
    except json.JSONDecodeError as exc:
        _fail(where, exc.lineno, f"not valid JSON ({exc.msg})")
    except RecursionError:
        _fail(where, None, "not a readable JSON file (nested too deeply)")
    except ValueError as exc:  # a value the decoder refuses (an integer of 5000 digits)
        _fail(where, None, f"not a readable JSON file ({str(exc).split(';')[0]})")
    if not isinstance(data, dict):
        _fail(where, None, "not an Ouster metadata file (JSON object expected)")
    intr = data.get("beam_intrinsics") if isinstance(data.get("beam_intrinsics"), dict) else data
    info = data.get("sensor_info") if isinstance(data.get("sensor_info"), dict) else data
    fmt = data.get("lidar_data_format") if isinstance(data.get("lidar_data_format"), dict) \
        else data.get("data_format") if isinstance(data.get("data_format"), dict) else {}
    cfg = data.get("config_params") if isinstance(data.get("config_params"), dict) else data

    def line_of(key):
        i = text.find(f'"{key}"')
        return text.count("\n", 0, i) + 1 if i >= 0 else None

    alt, azi = intr.get("beam_altitude_angles"), intr.get("beam_azimuth_angles")
    for key, v in (("beam_altitude_angles", alt), ("beam_azimuth_angles", azi)):
        if not isinstance(v, list) or not v:
            _fail(where, line_of(key), f"'{key}' must be a list of numbers (degrees)"
                  if key in text else f"no '{key}': not an Ouster metadata file; accepted: "
                  + accepted_formats())
    if len(alt) != len(azi):
        _fail(where, line_of("beam_azimuth_angles"), f"beam_azimuth_angles has {len(azi)} "
              f"entries, beam_altitude_angles {len(alt)}")
    ppc = fmt.get("pixels_per_column")
    if ppc is not None and ppc != len(alt):
        _fail(where, line_of("pixels_per_column"), f"pixels_per_column is {ppc} but "
              f"{len(alt)} beam angles are given")
    prod = str(info.get("prod_line", ""))
    transform = intr.get("beam_to_lidar_transform")
    if transform is not None:
        if not isinstance(transform, list) or len(transform) != 16:
            _fail(where, line_of("beam_to_lidar_transform"),
                  "beam_to_lidar_transform must be 16 numbers (a 4x4 matrix, row-major)")
        nx = _number(transform[3], where, line_of("beam_to_lidar_transform"), "transform[0][3]")
        nz = _number(transform[11], where, line_of("beam_to_lidar_transform"), "transform[2][3]")
        origin_from = "beam_to_lidar_transform"
    elif "lidar_origin_to_beam_origin_mm" in intr:
        nx = _number(intr["lidar_origin_to_beam_origin_mm"], where,
                     line_of("lidar_origin_to_beam_origin_mm"), "lidar_origin_to_beam_origin_mm")
        nz, origin_from = 0.0, "lidar_origin_to_beam_origin_mm"
    else:
        nx = next((mm for p, mm in OUSTER_DEFAULT_ORIGIN_MM if prod.startswith(p)),
                  OUSTER_GEN1_ORIGIN_MM)
        nz, origin_from = 0.0, f"ouster-sdk's default for '{prod or 'gen 1'}'"
    origin = (nx * 1e-3, 0.0, nz * 1e-3)
    line_alt, line_azi = line_of("beam_altitude_angles"), line_of("beam_azimuth_angles")
    rows = [(line_alt, i, _number(a, where, line_alt, f"beam_altitude_angles[{i}]"),
             _number(b, where, line_azi, f"beam_azimuth_angles[{i}]"), origin)
            for i, (a, b) in enumerate(zip(alt, azi))]
    mode = cfg.get("lidar_mode") or data.get("lidar_mode")
    note = (f"prod_line={prod or '?'} build_rev={info.get('build_rev', '?')} "
            f"lidar_mode={mode or '?'} (the base's columns and rate kept); beam origin "
            f"{nx:g} mm (z {nz:g} mm) from {origin_from}; channel = beam index 0-based")
    return _result("ouster-json", rows, where, note, True)


# ---- dispatch -----------------------------------------------------------------------------

def _data_lines(text):
    return [(i, ln) for i, ln in enumerate(text.splitlines(), start=1)
            if ln.strip() and not ln.lstrip().startswith("#")]


_NUMERIC_ROW = re.compile(r"^\s*[-+]?[\d.]+(e[-+]?\d+)?\s*(,\s*[-+]?[\d.]+(e[-+]?\d+)?\s*)?,?\s*$",
                          re.IGNORECASE)


def read_calibration(path):
    """Read a unit's calibration file (format recognised from its content)."""
    path = Path(path)
    where = str(path)
    try:
        raw = path.read_bytes() if path.stat().st_size <= MAX_CALIBRATION_BYTES else None
    except FileNotFoundError:
        raise PresetError(f"{where}: calibration file not found") from None
    except OSError as exc:
        raise PresetError(f"{where}: cannot read calibration file ({exc.strerror})") from None
    if raw is None:
        raise PresetError(f"{where}: calibration file is more than {MAX_CALIBRATION_BYTES} bytes")
    try:
        text = raw.decode("utf-8-sig")
    except UnicodeDecodeError:
        raise PresetError(f"{where}: not a text file (UTF-8); accepted: "
                          f"{accepted_formats()}") from None
    head = text.lstrip()
    lines = _data_lines(text)
    if head.startswith("<"):
        cal = _velodyne_xml(text, where)
    elif head.startswith("{"):
        cal = _ouster(text, where)
    elif lines and "," in lines[0][1] and re.match(r"^\s*(channel|laser\s*_?id)\b",
                                                   lines[0][1], re.IGNORECASE):
        cal = _hesai(lines, where)
    elif lines and _NUMERIC_ROW.match(lines[0][1]):
        cal = _robosense(lines, where)
    elif re.search(r"^lasers\s*:", text, re.MULTILINE):
        cal = _velodyne_yaml(text, where)
    else:
        raise PresetError(f"{where}: not a calibration format RLS recognises; accepted: "
                          f"{accepted_formats()}")
    return UnitCalibration(cal.format, cal.channel_ids, cal.elevations_deg,
                           cal.azimuth_offsets_deg, cal.origins_m, cal.note, path.name,
                           hashlib.sha256(raw).hexdigest())

"""SUMO floating-car data (``sumo --fcd-output``) read and turned into box poses at a
scene's frame rate.

What FCD holds (SUMO documentation "Simulation/Output/FCDOutput",
sumo.dlr.de/docs/Simulation/Output/FCDOutput.html, checked against SUMO 1.28's output):
one ``<timestep time=...>`` per step with a ``<vehicle>`` or ``<person>`` per object in
the network; ``x``, ``y`` (and ``z`` where the network has elevation) are in the
network's coordinates (the net file's ``<location netOffset>`` is already applied) and
are the centre of the object's *front bumper*; ``angle`` is in degrees "in navigational
standard (0-360 degrees, going clockwise with 0 at the 12'o clock position)", 12
o'clock being the network's +y. Persons follow the same rule: SUMO's pedestrian model
places a person by the front of its walking extent (MSPModel_Striping, ``getPosition``
at ``myRelX``, with the body reaching ``length`` behind it). A person riding a vehicle
is written right after it, at the vehicle's position (``MSFCDExport::write`` writes
``veh->getPersons()`` with ``p->getPosition()``, the vehicle's front bumper; the
``vehicle`` attribute naming it is off by default): such a sample, a ``<person>`` at a
``<vehicle>``'s x, y in its timestep or with a ``vehicle``, is left out, so the person
is absent while it rides (it was a pedestrian standing in the car's bonnet). Output
written with ``--fcd-output.geo`` (longitude, latitude) is not in metres and is
refused, and so is ``--fcd-output.utm`` (named in SUMO's header comment): it writes
vehicles in unshifted coordinates (SUMO 1.28 leaves persons in the network's).

Conversion to Blender (world +x east, +y north, +z up; heading counter-clockwise from
+x): ``yaw = radians(90 - angle)``; the box's centre is the front minus half the
type's length along the heading: ``(x, y) - L/2 (cos yaw, sin yaw)``, minus the
``origin`` (the net coordinates that land on the scene's origin); the bottom of the box
is at ``z`` (0 where FCD has none).

Resampling: frame ``f`` is at simulation time ``begin + (f - first frame) / fps``. An
object is present at a frame time that is one of its FCD steps or lies between two of
its consecutive steps; there its pose is the linear interpolation of the two (headings
along the shorter arc). It is never extrapolated: before it appears and after it
leaves it is absent (within a gap its pose is held at the last present frame).
"""

import math
import os
import re
import xml.etree.ElementTree as ET
from dataclasses import dataclass, field

import numpy as np

from ..errors import InputError
from ..roads.network import refuse_internal_dtd
from .xml_errors import parse_reason

# A step of an object counts as consecutive with the next when they are at most this
# many FCD periods apart (SUMO writes every step, or every --device.fcd.period).
GAP_STEPS = 1.5
TIME_EPS = 1e-6
READ_MARGIN_S = 5.0
# SUMO writes angles in [0, 360); beyond ten turns either way an angle is not a heading
# (at 1e20 degrees float64 cannot tell headings 16,384 degrees apart).
ANGLE_LIMIT_DEG = 3600.0


@dataclass
class Track:
    """One vehicle or person in the FCD: its samples in time order."""
    id: str
    kind: str            # "vehicle" or "person"
    type: str
    times: list = field(default_factory=list)
    x: list = field(default_factory=list)
    y: list = field(default_factory=list)
    z: list = field(default_factory=list)
    angle: list = field(default_factory=list)


@dataclass
class Fcd:
    tracks: dict         # id -> Track (ids prefixed "person:" for persons)
    step: float          # the FCD period (s)
    first: float         # the first and last timestep (s)
    last: float
    path: str = "the FCD"

    @property
    def types(self):
        return {t.type for t in self.tracks.values()}


_ROOT_TAG = re.compile(rb"<([A-Za-z_][\w.:-]*)")
# SUMO's header comment lists the options it ran with
_UTM = re.compile(rb'<fcd-output\.utm\s+value="(?:true|on|yes|1|x)"', re.I)


def _root_tag(path):
    """The first element's name in the file's head (declarations and comments skipped),
    or None; ``InputError`` when SUMO's header comment says ``--fcd-output.utm``."""
    with open(path, "rb") as fh:
        head = fh.read(1 << 16)
    comments = b"".join(re.findall(rb"<!--.*?-->", head, flags=re.S))
    head = re.sub(rb"<\?.*?\?>|<!--.*?-->", b"", head, flags=re.S)
    m = _ROOT_TAG.search(head)
    if _UTM.search(comments):
        raise InputError(f"{path} was written with --fcd-output.utm (SUMO's header says "
                         f"so): its vehicles are in unshifted (UTM) coordinates, not the "
                         f"network's, and would miss the roads by the net's netOffset; "
                         f"write the FCD without --fcd-output.utm")
    return m.group(1).decode("ascii", "replace") if m else None


PROGRESS_STEPS = 500  # timesteps between two calls of read_fcd's progress


def read_fcd(path, begin=None, end=None, progress=None):
    """Read an FCD file, streamed (``iterparse``: a timestep's objects are read when it
    ends, then it is cleared). Keeps the steps within [begin, end] seconds when given. A
    file that is not XML, is cut short, or is not FCD raises ``InputError`` naming the
    line. ``progress(share of the file read)`` every ``PROGRESS_STEPS`` timesteps."""
    if not os.path.isfile(path):
        raise InputError(f"FCD file not found: {path}")
    refuse_internal_dtd(path)
    try:
        root = _root_tag(path)
        if root is not None and root != "fcd-export":
            raise InputError(f"{path} is not SUMO FCD output: its root element is <{root}>, "
                             f"not <fcd-export> (write it with sumo --fcd-output)")
        rows, steps = {}, []
        lo = -math.inf if begin is None else begin - TIME_EPS
        hi = math.inf if end is None else end + TIME_EPS
        fh = open(path, "rb")
        size = max(1, os.fstat(fh.fileno()).st_size)
        with fh:
            for t in _timesteps(fh, path, rows, steps, lo, hi):
                if progress is not None and len(steps) % PROGRESS_STEPS == 0:
                    progress(fh.tell() / size)
    except ET.ParseError as exc:
        raise InputError(f"{path} is not complete, well-formed XML (cut short or not "
                         f"FCD): {parse_reason(exc)}") from None
    except OSError as exc:
        raise InputError(f"cannot read FCD file {path}: {exc.strerror or exc}") from None
    if not steps:
        raise InputError(f"{path} has no <timestep>: is it SUMO FCD output?")
    times = np.unique(np.asarray(steps, float))
    step = float(np.min(np.diff(times))) if len(times) > 1 else 1.0
    tracks = {}
    for key, (kind, oid, typ, ts, xs, ys, zs, angles) in rows.items():
        tr = Track(oid, kind, typ)
        try:
            tr.x, tr.y, tr.z, tr.angle = (np.asarray(v, dtype=np.float64)
                                          for v in (xs, ys, zs, angles))
        except ValueError:
            raise InputError(f"{path}: <{kind} id={oid!r}> has a position or angle that "
                             f"is not a number") from None
        tr.times = np.asarray(ts, np.float64)
        if not all(np.isfinite(v).all() for v in (tr.x, tr.y, tr.z, tr.angle)):
            raise InputError(f"{path}: <{kind} id={oid!r}> has a position or angle that "
                             f"is not finite")
        wild = np.abs(tr.angle) > ANGLE_LIMIT_DEG
        if wild.any():
            i = int(np.argmax(wild))
            raise InputError(f"{path}: <{kind} id={oid!r}> at time {tr.times[i]:g} has angle "
                             f"{tr.angle[i]:g}: SUMO writes angles in [0, 360) degrees; RLS "
                             f"takes angles within +-{ANGLE_LIMIT_DEG:g}")
        order = np.argsort(tr.times, kind="stable")
        if (np.diff(order) != 1).any():
            for name in ("times", "x", "y", "z", "angle"):
                setattr(tr, name, getattr(tr, name)[order])
        tracks[key] = tr
    return Fcd(tracks, step, float(times[0]), float(times[-1]), path)


def _timesteps(fh, path, rows, steps, lo, hi):
    """Each timestep's time as it is read from ``fh``, its objects (within [lo, hi])
    added to ``rows``; a repeated or backward timestep is an ``InputError``."""
    for _, el in ET.iterparse(fh, events=("end",)):
        if el.tag != "timestep":
            continue
        t = _num(el.get("time"), "time", path, "timestep")
        if steps and t <= steps[-1] + TIME_EPS:
            raise InputError(
                f"{path}: <timestep time={el.get('time')!r}> (the {len(steps) + 1}th) "
                + ("repeats the timestep before it" if abs(t - steps[-1]) <= TIME_EPS
                   else f"goes back in time after time={steps[-1]:g}")
                + ": SUMO writes each step once, in time order; was the file joined "
                "from several runs?")
        steps.append(t)
        if lo <= t <= hi:
            # a person riding a vehicle is written beside it at the vehicle's own
            # position (its front bumper): it is inside the vehicle, not walking
            carried = {(o.get("x"), o.get("y")) for o in el if o.tag == "vehicle"}
            for obj in el:
                if obj.tag == "person" and (obj.get("vehicle") or (
                        obj.get("x") is not None
                        and (obj.get("x"), obj.get("y")) in carried)):
                    continue
                _add(rows, obj, t, path)
        el.clear()
        yield t


def _num(value, name, path, tag):
    try:
        v = float(value)
    except (TypeError, ValueError):
        v = math.nan
    if not math.isfinite(v):
        raise InputError(f"{path}: a <{tag}> with {name}={value!r}, not a number")
    return v


def _add(rows, el, t, path):
    tag = el.tag
    if tag != "vehicle" and tag != "person":
        return
    a = el.attrib
    oid = a.get("id")
    if oid is None:
        raise InputError(f"{path}: a <{tag}> without an id at time {t:g}")
    key = oid if tag == "vehicle" else "person:" + oid
    row = rows.get(key)
    if row is None:
        if "x" not in a and "lon" in a:
            raise InputError(f"{path} holds geo-coordinates (--fcd-output.geo): write the "
                             f"FCD in network coordinates (without --fcd-output.geo)")
        typ = a.get("type") or ("DEFAULT_PEDTYPE" if tag == "person" else "DEFAULT_VEHTYPE")
        row = rows[key] = (tag, oid, typ, [], [], [], [], [])
    else:
        if row[3][-1] == t:
            raise InputError(f"{path}: <{tag} id={oid!r}> appears twice in the timestep at "
                             f"time {t:g}: an id names one {tag} (two objects with one id "
                             f"would be merged into one that jumps between them)")
        typ = a.get("type")
        if typ is not None and typ != row[2]:
            raise InputError(f"{path}: <{tag} id={oid!r}> changes its type from {row[2]!r} "
                             f"to {typ!r} at time {t:g}: RLS sizes an object once, by one "
                             f"vType")
    try:
        row[4].append(a["x"])
        row[5].append(a["y"])
        row[7].append(a["angle"])
    except KeyError as exc:
        raise InputError(f"{path}: <{tag} id={oid!r}> at time {t:g} has no "
                         f"{exc.args[0]!r}") from None
    row[3].append(t)
    row[6].append(a.get("z", "0"))


def yaw_of_angle(angle_deg):
    """Blender yaw (radians, counter-clockwise from +x) of SUMO angles (degrees,
    clockwise from +y)."""
    return np.radians(90.0 - np.asarray(angle_deg, float))


def box_centre(x, y, angle_deg, length, origin=(0.0, 0.0)):
    """(cx, cy, yaw): the box centre of objects whose front bumper centre is (x, y)
    heading SUMO ``angle_deg``, in the scene (net coordinates minus ``origin``)."""
    yaw = yaw_of_angle(angle_deg)
    half = 0.5 * np.asarray(length, float)
    cx = np.asarray(x, float) - half * np.cos(yaw) - float(origin[0])
    cy = np.asarray(y, float) - half * np.sin(yaw) - float(origin[1])
    return cx, cy, yaw


@dataclass
class Motion:
    """One object over the frames it spans: ``first`` the index (into the frame times
    resampled at) of its first present frame; over that frame and the ones after it,
    up to its last present one: ``present`` (F,) bool (false in a gap), ``xyz`` (F, 3)
    the bottom centre of its box, ``yaw`` (F,) radians, continuous (unwrapped). Before
    ``first`` and after the last it is absent."""
    first: int
    present: np.ndarray
    xyz: np.ndarray
    yaw: np.ndarray

    @property
    def stop(self):
        return self.first + len(self.present)


# Blender's last frame (the hard maximum of Scene.frame_end in Blender 5.0: MAXFRAME).
MAX_FRAME = 1_048_574


def keyed_frames(fcd, fps, frame_start, begin=None, end=None):
    """(begin s, end s, number of frames) that an import keys: frame ``frame_start`` at
    ``begin`` (default the FCD's first step), one every 1/``fps`` s up to ``end``
    (default its last step); ``InputError`` when they would pass Blender's last frame."""
    check_times(begin, end)
    begin = fcd.first if begin is None else float(begin)
    end = fcd.last if end is None else float(end)
    n = int(math.floor((end - begin) * fps + 1e-6)) + 1
    if n < 1:
        raise InputError(f"--end {end:g} s is before --begin {begin:g} s")
    if frame_start + n - 1 > MAX_FRAME:
        raise InputError(f"{begin:g}-{end:g} s at {fps:g} fps is {n} frames from frame "
                         f"{frame_start}, past Blender's last frame ({MAX_FRAME}): choose a "
                         f"shorter stretch with --begin and --end")
    return begin, end, n


def frame_times(n_frames, fps, begin):
    """Simulation time (s) of each of ``n_frames`` frames from ``begin``."""
    return float(begin) + np.arange(int(n_frames)) / float(fps)


def step_notice(fps, step, begin, frame_start):
    """None when each frame is one FCD step (``fps`` x ``step`` = 1); else a line saying
    how the scene's frames map to SUMO's steps, and how to make them one to one."""
    per = float(fps) * float(step)
    if abs(per - 1.0) <= 1e-6:
        return None
    how = (f"each step spans {per:.3g} frames, interpolated between steps" if per > 1
           else f"frames are {1 / per:.3g} steps apart, the steps between them unkeyed")
    return (f"the FCD's step is {step:g} s and the scene runs at {fps:g} fps: frame f is "
            f"simulation time {begin:g} + (f - {frame_start}) / {fps:g} s, so {how}; set "
            f"the scene to {1 / step:g} fps to key one frame per SUMO step (a scene from "
            f"rls scene from-net runs at 10 fps, for rls traffic generate's 0.1 s)")


def resample(track, length, times, step, origin=(0.0, 0.0)):
    """``Motion`` of ``track`` (box length ``length``) at simulation ``times``
    (increasing): linear interpolation between consecutive FCD steps, headings by the
    shorter arc, no extrapolation (see the module doc). None when it is present at none
    of them. Only the times within the track's span are computed."""
    ts = np.asarray(track.times, float)
    all_times = np.asarray(times, float)
    lo = int(np.searchsorted(all_times, ts[0] - TIME_EPS))
    hi = int(np.searchsorted(all_times, ts[-1] + TIME_EPS, side="right"))
    if hi <= lo:
        return None
    times = all_times[lo:hi]
    cx, cy, yaw = box_centre(track.x, track.y, track.angle, length, origin)
    z = np.asarray(track.z, float)
    k = np.searchsorted(ts, times - TIME_EPS)          # first sample at or after t
    exact = (k < len(ts)) & (np.abs(ts[np.minimum(k, len(ts) - 1)] - times) <= TIME_EPS)
    inner = (k > 0) & (k < len(ts))
    k0, k1 = np.clip(k - 1, 0, len(ts) - 1), np.clip(k, 0, len(ts) - 1)
    gap = ts[k1] - ts[k0]
    between = inner & ~exact & (gap <= GAP_STEPS * step + TIME_EPS)
    present = exact | between
    idx = np.nonzero(present)[0]
    if not len(idx):
        return None
    a0, a1 = int(idx[0]), int(idx[-1]) + 1
    sl = slice(a0, a1)
    present, exact, between, k0, k1 = present[sl], exact[sl], between[sl], k0[sl], k1[sl]
    times = times[sl]
    a = np.where(between, (times - ts[k0]) / np.where(gap[sl] > 0, gap[sl], 1.0), 0.0)
    i0 = np.where(exact, k1, k0)
    dyaw = (yaw[k1] - yaw[i0] + math.pi) % (2 * math.pi) - math.pi   # shorter arc
    out_yaw = yaw[i0] + a * dyaw
    xyz = np.column_stack([cx[i0] + a * (cx[k1] - cx[i0]), cy[i0] + a * (cy[k1] - cy[i0]),
                           z[i0] + a * (z[k1] - z[i0])])
    if not present.all():  # a gap: hold the last present frame before it
        j = np.arange(len(present))
        src = np.maximum.accumulate(np.where(present, j, 0))
        xyz, out_yaw = xyz[src], out_yaw[src]
    return Motion(lo + a0, present, xyz, np.unwrap(out_yaw))


def default_vtypes_path(fcd_path):
    """``OUT.vtypes.xml`` beside ``OUT.xml``, where ``rls traffic generate`` writes the
    types; None when there is none."""
    base = fcd_path[:-4] if fcd_path.lower().endswith(".xml") else fcd_path
    path = base + ".vtypes.xml"
    return path if os.path.isfile(path) else None


def check_times(begin, end):
    """``InputError`` for a ``--begin`` or ``--end`` that is not a finite number of
    seconds, or an end before the begin."""
    for flag, v in (("--begin", begin), ("--end", end)):
        if v is not None and not math.isfinite(v):
            raise InputError(f"{flag} {v!r} is not a number of seconds")
    if begin is not None and end is not None and end < begin:
        raise InputError(f"--end {end:g} s is before --begin {begin:g} s")


def check_origin(origin):
    """``InputError`` for an ``--origin`` whose coordinates are not finite numbers."""
    if origin is not None and not all(math.isfinite(float(v)) for v in origin):
        raise InputError(f"--origin {' '.join(f'{float(v):g}' for v in origin)}: the "
                         f"origin's x and y must be finite numbers (network metres)")


def check_positions(fcd, types, origin):
    """``InputError`` naming the object and time when a box centre lands farther than
    ``extent.SPAN_M`` from the scene's origin: float32 keys would round it (a 1 m step
    is lost at 1e12 m) or overflow (1e300)."""
    from ..scene.extent import SPAN_M, check_span

    for tr in fcd.tracks.values():
        cx, cy, _ = box_centre(tr.x, tr.y, tr.angle, types[tr.type].length, origin)
        far = np.maximum(np.abs(cx), np.abs(cy))
        if far.max() > SPAN_M or not np.isfinite(far).all():
            i = int(np.argmax(np.where(np.isfinite(far), far, np.inf)))
            check_span([cx[i], cy[i], np.max(np.abs(tr.z))],
                       f"{fcd.path}: <{tr.kind} id={tr.id!r}> at time {tr.times[i]:g}",
                       "; --origin X Y names the network point at the scene's origin")
        check_span(tr.z, f"{fcd.path}: <{tr.kind} id={tr.id!r}>'s z")


def check_flat(fcd, tolerance, why):
    """``InputError`` naming the first object and time whose FCD ``z`` is more than
    ``tolerance`` from 0 (a network with elevation), when the scene's roads are flat
    (``why`` says so): its boxes would float above the roads or sink under them."""
    worst = None
    for tr in fcd.tracks.values():
        z = np.abs(tr.z)
        if len(z) and z.max() > tolerance and (worst is None or z.max() > worst[0]):
            i = int(np.argmax(z))
            worst = (float(z[i]), tr, i)
    if worst is not None:
        z, tr, i = worst
        raise InputError(
            f"{fcd.path}: <{tr.kind} id={tr.id!r}> at time {tr.times[i]:g} has z "
            f"{tr.z[i]:g} m: the FCD comes from a network with elevation, but {why}; "
            f"its road users would be keyed up to {z:.2f} m off the roads. Run SUMO on the "
            f"flattened network the scene was built from (netconvert --sumo-net-file NET "
            f"--flatten -o FLAT.net.xml; rls traffic generate FLAT.net.xml ...)")


def load(fcd_path, vtypes_paths=(), begin=None, end=None, progress=None):
    """(Fcd, {type id: VType}) of an FCD file with the vTypes of ``vtypes_paths`` (or
    of ``OUT.vtypes.xml`` beside it when none is given); every error an InputError.
    ``progress(share of the FCD read)`` as it is read."""
    from .vtypes import read_vtypes, resolve

    check_times(begin, end)
    # steps a little outside [begin, end] are kept for the interpolation at its ends
    fcd = read_fcd(fcd_path, None if begin is None else begin - READ_MARGIN_S,
                   None if end is None else end + READ_MARGIN_S, progress)
    if not fcd.tracks:
        raise InputError(f"{fcd_path} has no vehicle or person"
                         + (" between --begin and --end" if begin is not None
                            or end is not None else ""))
    paths = list(vtypes_paths) or [p for p in [default_vtypes_path(fcd_path)] if p]
    known = {}
    for p in paths:
        if not os.path.isfile(p):
            raise InputError(f"vType file not found: {p}")
        known.update(read_vtypes(p))
    types = resolve(fcd.types, known, fcd_path)
    check_person_types(fcd, types)
    return fcd, types


def check_person_types(fcd, types):
    """Refuse a person whose vType is not a pedestrian's (``VType.label``). SUMO 1.28
    gives a vType without a vClass the passenger class and its sizes, persons' too (it
    warns that the person 'receives type ... which implicitly uses unsuitable vClass
    'passenger''), and walks them with a 5 m body behind the FCD's point: RLS would key
    a car-sized 'vehicle' on the sidewalk. The fix is SUMO's own."""
    bad = sorted({tr.type for tr in fcd.tracks.values()
                  if tr.kind == "person" and types[tr.type].label != "pedestrian"})
    if bad:
        tid = bad[0]
        vt = types[tid]
        more = f" (and {len(bad) - 1} more: {', '.join(map(repr, bad[1:4]))})" \
            if len(bad) > 1 else ""
        raise InputError(
            f"{fcd.path}: persons walk with vType {tid!r}{more}, whose vClass is "
            f"{vt.vclass!r}: SUMO gave them that class's {vt.length:g} m body (it warns "
            f"'unsuitable vClass'), not a pedestrian's. Give the vType "
            f"vClass=\"pedestrian\" and run SUMO again")

"""The per-hit stage of a frame: from what each ray brought back to the point records.

Per ray: the intensity (reflectivity x |cos incidence|, CARLA's attenuation when set;
ghosts bring their own), the range with its noise, CARLA's dropout, and for the rays
kept their point records. ``assemble`` runs it in C (``native/c/points.c``, in the
library of the compiled Embree loop, on all cores) where that library is built, else
in numpy (``assemble_numpy``): the readable reference the C code follows operation by
operation, so both write the same bytes (tests/core/test_assemble.py). Every random
number is drawn before, in numpy, from the scan's seeded generator (``Draws``): the
bytes never depend on the path.

Frames with CARLA's attenuation, detection by the LiDAR equation (``detection``),
weather (its two-way transmission and false returns from the air, ``weather``),
another reported intensity than CARLA's, or beam footprints that changed a return
(``footprint``: echoes detected there, second echoes as extra rows) work out each
ray's intensity and detection in numpy (``_assemble_lidar_equation``: exp, log and
tanh are numpy's), and the noise, dropout and records in C like any frame.
"""

import ctypes
from dataclasses import dataclass, field

import numpy as np

from ..native import kernels
from . import weather as wx
from ..native.kernels import Kernel
from ..labels import WEATHER_LABEL
from ..points import point_dtype
from ..native.vectors import row_dot

# The fields points.c knows, in its enum's order.
FIELD_ORDER = ("x", "y", "z", "range", "intensity", "ring", "time", "label", "instance",
               "ghost", "return_index", "num_returns")
NATIVE_POINTS_ABI = 4


@dataclass
class Draws:
    """The random numbers of a frame's effects, one per ray, drawn up front."""

    noise: np.ndarray | None = None      # float32 range noise (m)
    general: np.ndarray | None = None    # uniforms of the general dropout
    low: np.ndarray | None = None        # uniforms of the low-intensity dropout
    # Drawn after the above, only when used (so other frames keep their streams):
    detect: np.ndarray | None = None     # uniforms of detection by the LiDAR equation
    medium: np.ndarray | None = None     # uniforms: does the air send a false return
    medium_range: np.ndarray | None = None  # uniforms: its range (weather.false_return_ranges)


@dataclass
class Hits:
    """What each ray brought back (``frame.Returns`` after ghosts) and the tables its
    indices point into."""

    dist: np.ndarray       # (N,) float64 range
    valid: np.ndarray      # (N,) bool
    surface: np.ndarray    # (N, 2) int32 object, material
    normals: np.ndarray    # (N, 3) float64
    ghost: np.ndarray | None          # (N,) uint8 or None
    ghost_rows: np.ndarray            # rows whose light came back by a bounce
    ghost_dot: np.ndarray             # (G,) cos of each to its last leg
    ghost_intensity: np.ndarray       # (G,) its intensity
    reflectivity: np.ndarray          # per material, float64
    labels: np.ndarray                # per object, uint32
    instances: np.ndarray             # per object, uint32
    # Rows whose return is a false one from the air (weather), and its range
    medium_rows: np.ndarray = field(default_factory=lambda: np.zeros(0, np.int64))
    medium_dist: np.ndarray = field(default_factory=lambda: np.zeros(0))
    # Rows whose return is an echo of their beam's footprint (``footprint``): detected
    # there already, with the echo's effective rho |cos| and CARLA intensity (before
    # T^2); per row, each point's return index and its pulse's number of returns
    # (None: 1 and 1)
    echo_rows: np.ndarray = field(default_factory=lambda: np.zeros(0, np.int64))
    echo_rho_cos: np.ndarray = field(default_factory=lambda: np.zeros(0))
    echo_carla: np.ndarray = field(default_factory=lambda: np.zeros(0))
    return_index: np.ndarray | None = None
    num_returns: np.ndarray | None = None


@dataclass
class Rays:
    """Where the rays went: world directions and origins, and the pattern's own
    columns (sensor-frame directions, rings, times)."""

    dirs: np.ndarray        # (N, 3) world unit directions
    origins: np.ndarray     # (1, 3) or (N, 3)
    columns: tuple          # 3 x (N,) sensor-frame direction components
    rings: np.ndarray       # (N,) uint16
    times: np.ndarray       # (N,) float64


@dataclass
class Effects:
    general_rate: float = 0.0
    intensity_limit: float = 0.0
    intensity_zero: float = 0.0
    attenuation_per_m: float = 0.0
    detection: object = None        # detection.DetectionModel, or None: CARLA's model
    intensity: str = "carla"        # what is reported (detection.INTENSITY_MODES)
    alpha: float = 0.0              # extinction coefficient of the air (1/m, weather)

    @property
    def plain(self):
        """Today's CARLA model in clear air: what points.c computes."""
        return self.detection is None and self.intensity == "carla" and not self.alpha


def intensities(hits, dirs, attenuation_per_m=0.0):
    """(intensity, cos) per ray: reflectivity x |cos| clipped to 0..1 (x exp(-a d) with
    attenuation), the ghosts' own where they came back by a bounce."""
    dot = row_dot(hits.normals, dirs)
    inten = hits.reflectivity[hits.surface[:, 1]] * np.abs(dot)
    if attenuation_per_m:
        inten = inten * np.exp(-float(attenuation_per_m)
                               * np.where(hits.valid, hits.dist, 0.0))
    inten = np.clip(inten, 0.0, 1.0)
    if len(hits.ghost_rows):
        dot[hits.ghost_rows] = hits.ghost_dot
        inten[hits.ghost_rows] = hits.ghost_intensity
    return inten, dot


def assemble_numpy(hits, rays, draws, effects, frame_space, fields=None):
    """The reference: (points, index of each point's ray, back-face flag per point)."""
    return _assemble(None, hits, rays, draws, effects, frame_space, fields)


def _assemble(fn, hits, rays, draws, effects, frame_space, fields):
    """``assemble`` with the compiled per-hit stage ``fn`` (None: numpy)."""
    if not effects.plain or len(hits.medium_rows) or len(hits.echo_rows):
        return _assemble_lidar_equation(fn, hits, rays, draws, effects, frame_space, fields)
    if fn is not None and not effects.attenuation_per_m:
        return _assemble_native(fn, hits, rays, draws, effects, frame_space, fields)
    inten, dot = intensities(hits, rays.dirs, effects.attenuation_per_m)
    return _kept_points(fn, hits, rays, draws, effects, frame_space, fields,
                        hits.valid.copy(), hits.dist, inten, dot, None)


def _kept_points(fn, hits, rays, draws, effects, frame_space, fields, keep, dist, inten,
                 dot, medium):
    """The noise, the dropout and the records of the rays ``keep`` (bool per ray), from
    per-ray ranges, intensities and cosines worked out already; ``medium`` (bool per
    ray or None): false returns from the air. In C with ``fn``, else numpy."""
    if fn is not None:
        return _assemble_native(fn, hits, rays, draws, effects, frame_space, fields,
                                given=(keep, dist, inten, dot, medium))
    idx, d = _noise_and_dropout(keep, dist, inten, draws, effects)
    pts = _records(hits, rays, idx, d, inten, frame_space, fields,
                   None if medium is None else medium[idx])
    return pts, idx, dot[idx] > 0


def _noise_and_dropout(keep, dist, inten, draws, effects):
    """(rays kept, their noisy ranges): ``keep`` (bool per ray, changed here) less the
    general and the low-intensity dropout and less ranges that noise made <= 0."""
    d = dist if draws.noise is None else dist + draws.noise
    if draws.general is not None:
        keep &= draws.general >= effects.general_rate
    if draws.low is not None:
        p = (effects.intensity_zero / effects.intensity_limit) * inten \
            + (1.0 - effects.intensity_zero)
        keep &= ~(inten <= effects.intensity_limit) | (draws.low < p)
    keep &= d > 0
    idx = np.nonzero(keep)[0]
    return idx, d[idx]


def _records(hits, rays, idx, d, inten, frame_space, fields, medium=None):
    """The point records of rays ``idx`` at ranges ``d``; ``medium`` (bool per point):
    false returns from the air, labelled ``WEATHER_LABEL``, instance 0, no ghost."""
    obj = hits.surface[idx, 0]
    dtype = point_dtype(fields)
    pts = np.empty(len(idx), dtype=dtype)
    want = set(dtype.names)
    for k, f in enumerate("xyz"):
        if f not in want:
            continue
        if frame_space == "world":
            np.multiply(rays.dirs[idx, k], d, out=pts[f])
            pts[f] += rays.origins[0, k] if rays.origins.shape[0] == 1 else rays.origins[idx, k]
        else:
            np.multiply(rays.columns[k].take(idx), d, out=pts[f])
    columns = {"range": lambda: d, "intensity": lambda: inten.take(idx),
               "ring": lambda: rays.rings.take(idx), "time": lambda: rays.times.take(idx),
               "label": lambda: hits.labels[obj], "instance": lambda: hits.instances[obj],
               "ghost": lambda: 0 if hits.ghost is None else hits.ghost.take(idx),
               "return_index": lambda: 1 if hits.return_index is None
               else hits.return_index.take(idx),
               "num_returns": lambda: 1 if hits.num_returns is None
               else hits.num_returns.take(idx)}
    for f, column in columns.items():
        if f in want:
            pts[f] = column()
    if medium is not None and medium.any():
        m = np.nonzero(medium)[0]
        for f, value in (("label", WEATHER_LABEL), ("instance", 0), ("ghost", 0)):
            if f in want:
                pts[f][m] = value
    return pts


def _assemble_lidar_equation(fn, hits, rays, draws, effects, frame_space, fields):
    """``assemble_numpy`` with detection by the LiDAR equation, weather or a device's
    own intensity (see ``detection``, ``weather``). Per ray, with T^2 = exp(-2 alpha R):
    a false return from the air replaces the ray's return where one was drawn (frame
    decides, ``hits.medium_rows``); received power P = rho |cos| T^2 / R^2; the ray is
    detected when its uniform is below p(P) (false returns are detected by
    construction); the intensity is what the device reports; then noise and CARLA's
    dropout as in the plain model."""
    model, alpha = effects.detection, float(effects.alpha)
    dot = row_dot(hits.normals, rays.dirs)
    rho_cos = hits.reflectivity[hits.surface[:, 1]] * np.abs(dot)
    # CARLA's intensity, only for a device that reports neither reflectivity nor strength
    carla = None
    if effects.intensity not in ("reflectivity", "strength"):
        carla = rho_cos
        if effects.attenuation_per_m:
            carla = carla * np.exp(-float(effects.attenuation_per_m)
                                   * np.where(hits.valid, hits.dist, 0.0))
        carla = np.clip(carla, 0.0, 1.0)
    g = hits.ghost_rows
    if len(g):
        dot[g] = hits.ghost_dot
        rho_cos[g] = hits.ghost_intensity
        if carla is not None:
            carla[g] = hits.ghost_intensity
    e = hits.echo_rows
    if len(e):
        rho_cos[e] = hits.echo_rho_cos
        if carla is not None:
            carla[e] = hits.echo_carla
    dist, valid = hits.dist, hits.valid
    m = hits.medium_rows
    medium = None
    if len(m):
        dist, valid = dist.copy(), valid.copy()
        dist[m], valid[m] = hits.medium_dist, True
        rho = wx.medium_reflectivity(alpha)
        rho_cos[m], dot[m] = rho, -1.0
        if carla is not None:
            carla[m] = np.clip(rho * np.exp(-float(effects.attenuation_per_m) * dist[m]),
                               0.0, 1.0)
        medium = np.zeros(len(dist), bool)
        medium[m] = True
    r = np.where(valid, dist, 1.0)
    t2 = wx.transmission2(alpha, r) if alpha else 1.0
    power = None
    if model is not None:
        power = rho_cos * t2 / (r * r)
    keep = valid.copy()
    if model is not None:
        excess = model.excess(power)  # ln(P / P50), for the detection and the strength
        detected = draws.detect < model.probability_of(power, excess)
        if medium is not None:
            detected |= medium
        if len(e):  # detected echo by echo (echoes.resolve)
            detected[e] = True
        keep &= detected
    if effects.intensity == "reflectivity":
        inten = np.clip(rho_cos * t2, 0.0, 1.0)
    elif effects.intensity == "strength":
        inten = model.strength(power, excess)
    else:
        inten = carla * t2
    return _kept_points(fn, hits, rays, draws, effects, frame_space, fields, keep, dist,
                        inten, dot, medium)


class _PointsArgs(ctypes.Structure):
    """``points_t`` of native/c/points.c."""

    _fields_ = [("n", ctypes.c_int64), ("dist", ctypes.c_void_p), ("valid", ctypes.c_void_p),
                ("surface", ctypes.c_void_p), ("normal", ctypes.c_void_p),
                ("dir", ctypes.c_void_p), ("ghost", ctypes.c_void_p),
                ("ghost_dot", ctypes.c_void_p), ("ghost_int", ctypes.c_void_p),
                ("refl", ctypes.c_void_p), ("label", ctypes.c_void_p),
                ("instance", ctypes.c_void_p), ("noise", ctypes.c_void_p),
                ("u_general", ctypes.c_void_p), ("general_rate", ctypes.c_double),
                ("u_low", ctypes.c_void_p), ("limit", ctypes.c_double),
                ("zero", ctypes.c_double), ("world", ctypes.c_int),
                ("origin", ctypes.c_void_p), ("origin_per_ray", ctypes.c_int),
                ("cols", ctypes.c_void_p * 3), ("ring", ctypes.c_void_p),
                ("time", ctypes.c_void_p), ("offsets", ctypes.c_int64 * len(FIELD_ORDER)),
                ("itemsize", ctypes.c_int64), ("inten_in", ctypes.c_void_p),
                ("dot_in", ctypes.c_void_p), ("medium", ctypes.c_void_p),
                ("medium_label", ctypes.c_uint32), ("ret_index", ctypes.c_void_p),
                ("num_ret", ctypes.c_void_p), ("out", ctypes.c_void_p),
                ("index", ctypes.c_void_p), ("back", ctypes.c_void_p)]


POINTS = Kernel("rls_points_assemble", "rls_points_abi", NATIVE_POINTS_ABI,
                [ctypes.POINTER(_PointsArgs), ctypes.c_int], ctypes.c_int64)


def native():
    """The compiled per-hit stage, or None (the reason in ``native_error()``)."""
    return POINTS.get()


def native_error():
    return POINTS.error


# Off: every frame assembles in numpy (the reference the C code is tested against).
compiled = True


def assemble(hits, rays, draws, effects, frame_space, fields=None):
    """(points, ray index per point, back-face flag per point): in C where it is built,
    else ``assemble_numpy``; the same bytes either way."""
    return _assemble(native() if compiled else None, hits, rays, draws, effects, frame_space,
                     fields)


def _c(a, dtype):
    return np.ascontiguousarray(a, dtype=dtype)


def _assemble_native(fn, hits, rays, draws, effects, frame_space, fields, given=None):
    """The C per-hit stage; ``given``: (keep, dist, intensity, cos, medium or None) per
    ray, worked out in numpy (``_kept_points``), else points.c shades the hits."""
    n = len(hits.dist)
    dtype = point_dtype(fields)
    keep = []  # every array the C code reads, alive until it returns

    def ptr(a, dt):
        if a is None:
            return None
        a = _c(a, dt)
        keep.append(a)
        return a.ctypes.data

    valid, dist, inten, dot, medium = (hits.valid, hits.dist, None, None, None) \
        if given is None else given
    ghost_dot = ghost_int = None
    if given is None and len(hits.ghost_rows):
        ghost_dot, ghost_int = np.zeros(n), np.zeros(n)
        ghost_dot[hits.ghost_rows] = hits.ghost_dot
        ghost_int[hits.ghost_rows] = hits.ghost_intensity
    world = frame_space == "world"
    args = _PointsArgs(
        n=n, dist=ptr(dist, np.float64), valid=ptr(valid, np.uint8),
        surface=ptr(hits.surface, np.int32), normal=ptr(hits.normals, np.float64),
        dir=ptr(rays.dirs, np.float64), ghost=ptr(hits.ghost, np.uint8),
        ghost_dot=ptr(ghost_dot, np.float64), ghost_int=ptr(ghost_int, np.float64),
        refl=ptr(hits.reflectivity, np.float64), label=ptr(hits.labels, np.uint32),
        instance=ptr(hits.instances, np.uint32), noise=ptr(draws.noise, np.float32),
        u_general=ptr(draws.general, np.float64), general_rate=effects.general_rate,
        u_low=ptr(draws.low, np.float64), limit=effects.intensity_limit,
        zero=effects.intensity_zero, world=int(world),
        origin=ptr(rays.origins, np.float64),
        origin_per_ray=int(rays.origins.shape[0] != 1),
        ring=ptr(rays.rings, np.uint16), time=ptr(rays.times, np.float64),
        itemsize=dtype.itemsize, inten_in=ptr(inten, np.float64), dot_in=ptr(dot, np.float64),
        medium=ptr(medium, np.uint8), medium_label=WEATHER_LABEL,
        ret_index=ptr(hits.return_index, np.uint8), num_ret=ptr(hits.num_returns, np.uint8))
    if not world:
        for k in range(3):
            args.cols[k] = ptr(rays.columns[k], np.float64)
    for k, f in enumerate(FIELD_ORDER):
        args.offsets[k] = dtype.fields[f][1] if f in dtype.names else -1
    # Room for a point per ray, shrunk in place to the points written (realloc keeps
    # the start; pages past the points are never touched).
    out, index, back = np.empty(n, dtype=dtype), np.empty(n, np.int64), np.empty(n, np.uint8)
    args.out, args.index, args.back = out.ctypes.data, index.ctypes.data, back.ctypes.data
    got = fn(ctypes.byref(args), kernels.threads())
    for a in (out, index, back):
        a.resize(got, refcheck=False)
    return out, index, back.view(bool)

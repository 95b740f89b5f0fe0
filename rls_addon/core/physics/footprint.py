"""Beam footprints and multiple returns (see docs/realism.md).

A beam is a cone of the preset's divergence, not a line. It is sampled only where that
can matter: the central rays are cast as always; rays next to a depth discontinuity (a
neighbour in the pattern that hits where it does not, or whose hit lies more than
``DEPTH_STEP`` x the echo separation off the plane of its own, and it off the
neighbour's) cast ``RING`` sub-rays on a ring at the cone's edge; where every sub-ray
meets the centre's object within the echo separation of its range, nothing changes.

The beam's profile is a Gaussian whose 1/e^2 radius is half the divergence (a stated
reading of the datasheets' "divergence"); the centre ray carries ``CENTRE_SHARE`` = 1/2
of the energy and each ring sub-ray (at the 1/e^2 radius) 1/12: the seven samples have
the Gaussian's second and fourth radial moments (w^2/2 and w^4/2) exactly.

The samples are grouped into echoes by range, detected and chosen as the device reports
them in ``echoes``.
"""

import ctypes
import dataclasses
import math
from dataclasses import dataclass

import numpy as np

from . import depth_edges
from .depth_edges import candidates, neighbour_pairs
from ..native.kernels import Kernel, threads

RING = 6                   # sub-rays on the ring at the 1/e^2 radius
CENTRE_SHARE = 0.5         # the centre ray's share of the beam's energy
RING_SHARE = (1.0 - CENTRE_SHARE) / RING
# Two echoes closer than this are one (mixed) echo: "the sensor records both returns
# only when the separation between the two objects is one meter or more" (Velodyne
# VLS-128 User Manual 63-9483 Rev A, 6.2.3 Dual Return Mode).
ECHO_SEPARATION_M = 1.0
RETURN_MODES = ("strongest", "last", "dual")
RLS_MAX_SHARES = 64         # native/c/rls_shares.h
_AMBIGUOUS_CAP = 1024       # directed pairs per share left to numpy (else: two steps)
# Neighbouring rays whose hits lie off each other's plane by more than this share of the
# echo separation (0.1 m for 1 m) mark a depth step worth sampling: smaller steps move
# a mixed point by less than that (a stated choice, about 5 sigma of the presets' range
# noise of 2 cm)
DEPTH_STEP = 0.1


@dataclass(frozen=True)
class Beam:
    """A preset's ``[beam]`` table: full divergence angles (horizontal, vertical, rad),
    the device's return mode and its echo separation (m)."""

    divergence_rad: tuple = (0.0, 0.0)
    return_mode: str = "strongest"
    echo_separation_m: float = ECHO_SEPARATION_M

    @property
    def sampled(self):
        return max(self.divergence_rad) > 0.0

    def to_dict(self):
        return {"model": "footprint", "divergence_rad": list(self.divergence_rad),
                "return_mode": self.return_mode,
                "echo_separation_m": self.echo_separation_m, "sub_rays": RING,
                "centre_share": CENTRE_SHARE}


def beam_of(preset, settings):
    """The ``Beam`` a scan samples (its return mode after the setting's), or None: no
    divergence in the preset, or ``settings.footprint`` is "off"."""
    beam = getattr(preset, "beam", None)
    if beam is None or not beam.sampled or settings.footprint != "auto":
        return None
    if settings.return_mode not in (None, "preset") and settings.return_mode != beam.return_mode:
        beam = Beam(beam.divergence_rad, settings.return_mode, beam.echo_separation_m)
    return beam


def footprint_info(preset, settings):
    """The sidecar's record of the beam model of a scan."""
    beam = getattr(preset, "beam", None)
    if beam is None or not beam.sampled:
        return {"model": "thin_ray", "reason": "no beam divergence in the preset"}
    if settings.footprint != "auto":
        return {"model": "thin_ray", "reason": f"footprint = '{settings.footprint}'"}
    return beam_of(preset, settings).to_dict()


def ring_directions(dirs, divergence_rad, k=None, basis=None):
    """(C, RING, 3) unit sub-ray directions on the ring at the 1/e^2 radius (half the
    divergence) around each of ``dirs`` (C, 3): the first horizontal, then every
    360 / RING degrees; an elliptical beam (horizontal != vertical) has an elliptical
    ring. With ``k`` (C,) ring indices: only those, (C, 3). ``basis``: ``_basis(dirs)``
    if the caller has it already."""
    d = np.asarray(dirs, np.float64)
    u, v = _basis(d) if basis is None else basis
    h, vert = (math.tan(0.5 * float(x)) for x in divergence_rad)
    if k is not None:
        phi = 2.0 * np.pi * np.asarray(k) / RING
        out = d + (h * np.cos(phi))[:, None] * u + (vert * np.sin(phi))[:, None] * v
        return out / np.linalg.norm(out, axis=1, keepdims=True)
    phi = 2.0 * np.pi * np.arange(RING) / RING
    out = d[:, None, :] + (h * np.cos(phi))[None, :, None] * u[:, None, :] \
        + (vert * np.sin(phi))[None, :, None] * v[:, None, :]
    return out / np.linalg.norm(out, axis=2, keepdims=True)


def _basis(d):
    """(u, v): unit vectors across each of the unit directions ``d`` (C, 3), u
    horizontal."""
    up = np.zeros_like(d)
    up[:, 2] = 1.0
    up[np.abs(d[:, 2]) > 0.999] = (1.0, 0.0, 0.0)   # a ray along the vertical
    u = np.cross(d, up)
    u /= np.linalg.norm(u, axis=1, keepdims=True)
    return u, np.cross(u, d)


def _sectors(dirs, i, j, di, u, v, divergence_rad):
    """(C,) the ring sector of each ray i (direction ``di``, basis ``u``, ``v``) nearest
    the direction of its neighbour j."""
    delta = dirs.take(j, axis=0) - di
    h, vert = (max(math.tan(0.5 * float(x)), 1e-12) for x in divergence_rad)
    phi = np.arctan2(np.einsum("ck,ck->c", delta, v) / vert,
                     np.einsum("ck,ck->c", delta, u) / h)
    return np.rint(phi / (2.0 * np.pi / RING)).astype(np.int64) % RING


def probe_rays_numpy(a, b, dirs, divergence_rad):
    """The reference: (pi, pk, pdir), the probes of the pairs (a, b) across a depth
    edge: for each ray and each neighbour across an edge, the ring sub-ray (sector pk)
    nearest the neighbour's direction, each (ray, sector) once, in (ray, sector)
    order."""
    i = np.concatenate([a, b])
    j = np.concatenate([b, a])
    di = dirs.take(i, axis=0)
    u, v = _basis(di)
    k = _sectors(dirs, i, j, di, u, v, divergence_rad)
    key, first = np.unique(i * RING + k, return_index=True)
    pi, pk = key // RING, key % RING
    pdir = ring_directions(dirs[pi], divergence_rad, pk,
                           (u.take(first, axis=0), v.take(first, axis=0)))
    return pi, pk, pdir


def probe_rays(a, b, dirs, divergence_rad):
    """``probe_rays_numpy``'s (pi, pk, pdir), in C where it is built (native/c/probes.c)."""
    if not compiled or PROBE_SECTORS.get() is None or RING_RAYS.get() is None:
        return probe_rays_numpy(a, b, dirs, divergence_rad)
    dirs = np.ascontiguousarray(dirs, np.float64)
    a, b = np.ascontiguousarray(a, np.int64), np.ascontiguousarray(b, np.int64)
    mask = np.zeros(len(dirs), np.uint8)
    amb = np.empty(2 * len(a), np.int64)
    h, vert = _half_axes(divergence_rad)
    args = _SectorsArgs(len(a), a.ctypes.data, b.ctypes.data, dirs.ctypes.data, h, vert,
                        2.0 * np.pi / RING, mask.ctypes.data, amb.ctypes.data)
    n_amb = PROBE_SECTORS.get()(ctypes.byref(args))
    _numpy_sectors(mask, amb[:n_amb], a, b, dirs, divergence_rad)
    return _ring_rays(None, mask, dirs, divergence_rad)


def edge_probes(pattern, hit, dist, normals, dirs, origins, step, divergence_rad):
    """(pi, pk, pdir): the probes of the pattern's neighbour pairs across a depth edge
    (``probe_rays`` of ``depth_edges.candidates``' pairs). In C where it is built, in
    one pass (native/c/edges.c: rls_edge_sectors): the pairs' rays are read once and no
    list of the pairs across an edge is made."""
    fused = EDGE_SECTORS.get() if compiled and depth_edges.compiled else None
    if fused is None or RING_RAYS.get() is None:
        a, b = candidates(pattern, hit, dist, normals, dirs, origins, step)
        return probe_rays(a, b, dirs, divergence_rad)
    a, b = neighbour_pairs(pattern)
    dirs = np.ascontiguousarray(dirs, np.float64)
    edges, _keep = depth_edges.edges_args(a, b, hit, dist, normals, dirs, origins, step)
    mask = np.zeros(len(dirs), np.uint8)
    amb = np.empty(_AMBIGUOUS_CAP * RLS_MAX_SHARES, np.int64)
    h, vert = _half_axes(divergence_rad)
    args = _EdgeSectorsArgs(ctypes.pointer(edges), h, vert, 2.0 * np.pi / RING,
                            mask.ctypes.data, amb.ctypes.data, _AMBIGUOUS_CAP)
    fused(ctypes.byref(args), threads())
    counts = list(args.n_ambiguous[:args.shares])
    if max(counts) > _AMBIGUOUS_CAP:  # a pathological frame: the two steps instead
        return probe_rays(*candidates(pattern, hit, dist, normals, dirs, origins, step),
                          dirs, divergence_rad)
    total = sum(args.n_probes[:args.shares])
    if sum(counts):
        t = np.concatenate([amb[k * _AMBIGUOUS_CAP:k * _AMBIGUOUS_CAP + m]
                            for k, m in enumerate(counts)])
        _numpy_sectors(mask, t, a, b, dirs, divergence_rad)
        total = None
    return _ring_rays(None, mask, dirs, divergence_rad, total)


def _half_axes(divergence_rad):
    return tuple(max(math.tan(0.5 * float(x)), 1e-12) for x in divergence_rad)


def _numpy_sectors(mask, t, a, b, dirs, divergence_rad):
    """Sets in ``mask`` the sectors of the directed pairs ``t`` (t: a[t] toward b[t];
    len(a) + t: b[t] toward a[t]) that the C code left to numpy: on a sector boundary
    to the last bits of atan2."""
    if not len(t):
        return
    i = np.concatenate([a, b])[t]
    j = np.concatenate([b, a])[t]
    di = dirs.take(i, axis=0)
    u, v = _basis(di)
    k = _sectors(dirs, i, j, di, u, v, divergence_rad)
    np.bitwise_or.at(mask, i, (1 << k).astype(np.uint8))


def whole_rings(rows, dirs, divergence_rad):
    """(len(rows) * RING, 3): ``ring_directions(dirs[rows])``, in C where it is built."""
    if not compiled or RING_RAYS.get() is None:
        return ring_directions(dirs[rows], divergence_rad).reshape(-1, 3)
    return _ring_rays(np.ascontiguousarray(rows, np.int64),
                      np.full(len(rows), (1 << RING) - 1, np.uint8),
                      np.ascontiguousarray(dirs, np.float64), divergence_rad)[2]


def _ring_rays(rows, mask, dirs, divergence_rad, total=None):
    """(ray, sector, direction) of each set bit of ``mask`` (per ray of ``rows``, or per
    ray of the frame when rows is None); ``total``: how many bits are set, if known."""
    h, vert = (math.tan(0.5 * float(x)) for x in divergence_rad)
    phi = 2.0 * np.pi * np.arange(RING) / RING     # as ring_directions has them
    hc, vs = np.ascontiguousarray(h * np.cos(phi)), np.ascontiguousarray(vert * np.sin(phi))
    mask = np.ascontiguousarray(mask, np.uint8)
    if total is None:
        total = int(np.unpackbits(mask).sum())
    ray, sector = np.empty(total, np.int64), np.empty(total, np.int64)
    out = np.empty((total, 3), np.float64)
    args = _RingArgs(len(mask), 0 if rows is None else rows.ctypes.data, mask.ctypes.data,
                     dirs.ctypes.data, hc.ctypes.data, vs.ctypes.data, ray.ctypes.data,
                     sector.ctypes.data, out.ctypes.data)
    RING_RAYS.get()(ctypes.byref(args))
    return ray, sector, out


class _SectorsArgs(ctypes.Structure):
    """``sectors_t`` of native/c/probes.c."""

    _fields_ = [("n", ctypes.c_int64), ("a", ctypes.c_void_p), ("b", ctypes.c_void_p),
                ("dir", ctypes.c_void_p), ("h", ctypes.c_double), ("vert", ctypes.c_double),
                ("sector", ctypes.c_double), ("mask", ctypes.c_void_p),
                ("ambiguous", ctypes.c_void_p)]


class _RingArgs(ctypes.Structure):
    """``ring_t`` of native/c/probes.c."""

    _fields_ = [("n", ctypes.c_int64), ("rows", ctypes.c_void_p), ("mask", ctypes.c_void_p),
                ("dir", ctypes.c_void_p), ("hc", ctypes.c_void_p), ("vs", ctypes.c_void_p),
                ("ray", ctypes.c_void_p), ("sector", ctypes.c_void_p),
                ("out", ctypes.c_void_p)]


class _EdgeSectorsArgs(ctypes.Structure):
    """``edge_sectors_t`` of native/c/edges.c."""

    _fields_ = [("e", ctypes.POINTER(depth_edges._EdgesArgs)), ("h", ctypes.c_double),
                ("vert", ctypes.c_double), ("sector", ctypes.c_double),
                ("mask", ctypes.c_void_p), ("ambiguous", ctypes.c_void_p),
                ("cap", ctypes.c_int64), ("shares", ctypes.c_int),
                ("n_ambiguous", ctypes.c_int64 * RLS_MAX_SHARES),
                ("n_probes", ctypes.c_int64 * RLS_MAX_SHARES)]


# Off: every frame works out its probes and rings in numpy (the reference the C code is
# tested against).
compiled = True
NATIVE_PROBES_ABI = 2
PROBE_SECTORS = Kernel("rls_probe_sectors", "rls_probes_abi", NATIVE_PROBES_ABI,
                       [ctypes.POINTER(_SectorsArgs)], ctypes.c_int64)
RING_RAYS = Kernel("rls_ring_rays", "rls_probes_abi", NATIVE_PROBES_ABI,
                   [ctypes.POINTER(_RingArgs)], ctypes.c_int64)
EDGE_SECTORS = Kernel("rls_edge_sectors", "rls_edges_abi", depth_edges.NATIVE_EDGES_ABI,
                      [ctypes.POINTER(_EdgeSectorsArgs), ctypes.c_int])


class SubRays:
    """The sub-rays of one frame's rays next to a depth edge, cast in two steps: first,
    for each ray and each neighbour across an edge, the one ring sub-ray nearest the
    neighbour's direction (the one most likely to reach across the edge); then the
    rest of the ring of the rays where such a probe disagrees with the centre (another
    object, no hit, or beyond the echo separation): a probe is one of its ring's
    sub-rays, and is not cast twice. A ray whose probes agree keeps its one return:
    its cone does not reach the edge toward any neighbour.

    ``rows``: the rays whose whole ring was sampled; ``dirs``, ``dist``, ``tri``,
    ``surface``, ``normals``: their RING sub-rays each, ray by ray; ``probes``: the
    probes cast; ``cast``: every sub-ray cast (probes and the rest of the rings)."""

    def __init__(self, beam, world, pattern, origins, dirs, times, ret, tri, rmax):
        hit = tri >= 0
        self.beam = beam
        sep = beam.echo_separation_m
        pi, pk, pdir = edge_probes(pattern, hit, ret.dist, ret.normals, dirs, origins,
                                   DEPTH_STEP * sep, beam.divergence_rad)
        times = np.asarray(times)
        self.rows = np.zeros(0, np.int64)
        self.count = self.probes = self.cast = 0
        if not len(pi):
            return
        o = origins if origins.shape[0] == 1 else origins[pi]
        pdist, body, ptri, pnormals = world.cast(o, pdir, times[pi], rmax)
        psurface = world.surface_ids(body, ptri)
        self.probes = self.cast = len(pi)
        phit = ptri >= 0
        chit = ret.valid[pi]
        with np.errstate(invalid="ignore"):
            off = (phit != chit) | (phit & ((psurface[:, 0] != ret.surface[pi, 0])
                                            | (np.abs(pdist - ret.dist[pi]) > sep)))
        c = np.unique(pi[off])
        self.rows = c
        self.count = len(c)
        if not len(c):
            return
        # the probes of these rays are their rings' sub-rays already: the rest is cast
        at = np.searchsorted(c, pi)
        mine = np.nonzero(c.take(np.minimum(at, len(c) - 1)) == pi)[0]
        slot = at[mine] * RING + pk[mine]
        todo = np.ones(len(c) * RING, bool)
        todo[slot] = False
        todo = np.nonzero(todo)[0]
        sub = whole_rings(c, dirs, beam.divergence_rad)
        ray = c[todo // RING]
        o = origins if origins.shape[0] == 1 else origins[ray]
        dist, body, tri2, normals = world.cast(o, sub[todo], times[ray], rmax)
        self.cast += len(todo)
        self.dirs = sub
        self.dist = np.empty(len(sub))
        self.tri = np.empty(len(sub), tri2.dtype)
        self.surface = np.empty((len(sub), 2), psurface.dtype)
        self.normals = np.empty((len(sub), 3))
        for out, mine_v, rest_v in ((self.dist, pdist, dist), (self.tri, ptri, tri2),
                                    (self.surface, psurface, world.surface_ids(body, tri2)),
                                    (self.normals, pnormals, normals)):
            out[slot] = mine_v[mine]
            out[todo] = rest_v


def split(hits, rays, draws, echoes):
    """The frame's ``Hits`` with the echoes applied to its own rows (each carries its
    echo's effective rho |cos| and intensity), and the second echoes (``dual``) as a
    small frame of their own: (hits, extra), extra = (hits, rays, draws) of one row per
    second echo, copies of its pulse's ray and draws, or None. Each row is assembled on
    its own, so the two frames give the points one frame of both would."""
    n, p = len(hits.dist), echoes.extra_parent
    main = dataclasses.replace(
        hits, echo_rows=echoes.rows, echo_rho_cos=echoes.rho_cos, echo_carla=echoes.carla,
        return_index=echoes.return_index[:n], num_returns=echoes.num_returns[:n])
    if not len(p):
        return main, None
    e = len(p)

    def pick(a):
        return None if a is None else np.asarray(a).take(p, axis=0)

    x_hits = dataclasses.replace(
        hits, dist=echoes.extra_dist, valid=np.ones(e, bool),
        surface=echoes.extra_surface.astype(hits.surface.dtype),
        normals=echoes.extra_normals, ghost=None, ghost_rows=np.zeros(0, np.int64),
        ghost_dot=np.zeros(0), ghost_intensity=np.zeros(0),
        medium_rows=np.zeros(0, np.int64), medium_dist=np.zeros(0),
        echo_rows=np.arange(e), echo_rho_cos=echoes.extra_rho_cos,
        echo_carla=echoes.extra_carla, return_index=echoes.return_index[n:],
        num_returns=echoes.num_returns[n:])
    x_rays = dataclasses.replace(
        rays, dirs=pick(rays.dirs),
        origins=rays.origins if rays.origins.shape[0] == 1 else pick(rays.origins),
        columns=tuple(pick(c) for c in rays.columns), rings=pick(rays.rings),
        times=pick(rays.times))
    x_draws = dataclasses.replace(draws, noise=pick(draws.noise), general=pick(draws.general),
                                  low=pick(draws.low), detect=pick(draws.detect))
    return main, (x_hits, x_rays, x_draws)


def merge(main, extra, parent):
    """The points of a frame (``main``: points, ray index, back flag; in ray order) and
    of its second echoes (``extra``: the same of the rows of ``split``'s extra frame,
    whose rays are ``parent``, ascending), each second echo right after its pulse's
    first: what a stable sort by ray of both would give, in one gather."""
    pts, idx, back = main
    x_pts, x_idx, x_back = extra
    x_idx = parent[x_idx]
    m, k = len(idx), len(x_idx)
    at = np.searchsorted(idx, x_idx, side="right") + np.arange(k)
    order = np.empty(m + k, np.int64)
    second = np.zeros(m + k, bool)
    second[at] = True
    order[~second] = np.arange(m)
    order[at] = m + np.arange(k)
    # the records as rows of bytes: numpy gathers structured records one field at a time
    rows = np.concatenate([_bytes(pts), _bytes(x_pts)]).take(order, axis=0)
    return (rows.reshape(-1).view(pts.dtype), np.concatenate([idx, x_idx])[order],
            np.concatenate([back, x_back])[order])


def _bytes(records):
    return records.view(np.uint8).reshape(len(records), records.dtype.itemsize)

"""A beam's echoes: its footprint's samples grouped by range, detected, and the ones the
device reports chosen (see ``footprint`` for the samples and docs/realism.md).

Sub-ray returns are grouped into echoes by range: sorted, a gap larger than the echo
separation starts a new echo. An echo's energy is the sum over its sub-rays of
share x rho x |cos| x T^2 / R^2 (the LiDAR equation's received power), its range the
energy-weighted mean of theirs (two surfaces closer than the separation give one mixed
point between them), its surface the sub-ray that sent the most. Each echo is detected
as ``detection`` says (presets with datasheet figures), or always (CARLA's model); the
device reports the strongest, the last, or both (``dual``) of the detected echoes.

``resolve`` groups and chooses in C where it is built (``native/c/echoes.c``), with the
detection curve and the air's transmission in numpy between; ``resolve_numpy`` is the
readable reference it follows operation by operation, and both give the same bytes
(tests/core/test_echoes_native.py).
"""

import ctypes
from dataclasses import dataclass, field

import numpy as np

from . import weather as wx
from .footprint import CENTRE_SHARE, RING, RING_SHARE
from ..native.kernels import Kernel


@dataclass
class Echoes:
    """What the footprint changed: rows of the frame whose return is an echo of their
    beam (their range, surface and normal are written into the frame's returns), the
    effective rho |cos| and CARLA intensity of each such row, and for ``dual`` the
    extra rows (second echoes) with their parent ray. ``return_index`` and
    ``num_returns`` per row of the extended frame (N + extra)."""

    rows: np.ndarray
    rho_cos: np.ndarray
    carla: np.ndarray
    extra_parent: np.ndarray
    extra_dist: np.ndarray
    extra_surface: np.ndarray
    extra_normals: np.ndarray
    extra_rho_cos: np.ndarray
    extra_carla: np.ndarray
    return_index: np.ndarray
    num_returns: np.ndarray
    stats: dict = field(default_factory=dict)


def _uniforms(key, rays, echo):
    """Uniforms in [0, 1) per (ray, echo), from a 64-bit counter hash (splitmix64) of
    the frame's key: per ray, whatever the other rays did."""
    with np.errstate(over="ignore"):
        x = np.uint64(key) + rays.astype(np.uint64) * np.uint64(RING + 1) \
            + echo.astype(np.uint64) + np.uint64(0x9E3779B97F4A7C15)
        x = (x ^ (x >> np.uint64(30))) * np.uint64(0xBF58476D1CE4E5B9)
        x = (x ^ (x >> np.uint64(27))) * np.uint64(0x94D049BB133111EB)
        x = x ^ (x >> np.uint64(31))
    return (x >> np.uint64(11)).astype(np.float64) * (1.0 / 9007199254740992.0)


def resolve_numpy(sub, ret, dirs, skip, refl, model, detect, key, alpha, atten, rmin, rmax):
    """The reference of ``resolve``: group each candidate's centre and sub-ray returns into echoes, detect them and
    choose what the device reports (``Echoes``; None when every candidate's sub-rays
    agree with its centre). ``skip``: rows left as they are (ghosts, false returns from
    the air); ``detect``: the frame's detection uniforms (None without a model);
    ``key``: the frame's key for the uniforms of echoes without the centre ray."""
    beam, sep = sub.beam, sub.beam.echo_separation_m
    c = sub.rows
    n_c = len(c)
    # (C, 1 + RING) samples: the centre, then the ring
    dist = np.concatenate([ret.dist[c][:, None], sub.dist.reshape(n_c, RING)], axis=1)
    surf = np.concatenate([ret.surface[c][:, None, :], sub.surface.reshape(n_c, RING, 2)], 1)
    nrm = np.concatenate([ret.normals[c][:, None, :], sub.normals.reshape(n_c, RING, 3)], 1)
    sdir = np.concatenate([dirs[c][:, None, :], sub.dirs.reshape(n_c, RING, 3)], axis=1)
    hit = np.isfinite(dist) & (dist >= rmin) & (dist <= rmax)
    hit[:, 0] &= ret.valid[c]
    hit[:, 1:] &= (sub.tri >= 0).reshape(n_c, RING)
    obj = surf[:, :, 0]
    agree = hit.all(axis=1) & (obj == obj[:, :1]).all(axis=1) \
        & (np.abs(np.where(hit, dist, 0.0) - dist[:, :1]) <= sep).all(axis=1)
    act = ~agree
    if skip is not None and len(skip):
        skipped = np.zeros(len(ret.dist), bool)  # a mask: np.isin sorts both
        skipped[skip] = True
        act &= ~skipped[c]
    stats = {"footprint_rays": int(n_c), "footprint_sub_rays": int(sub.cast)}
    if not act.any():
        return None, stats
    k = np.nonzero(act)[0]
    rays = c[k]
    m = len(k)
    S = 1 + RING
    dist, surf, nrm, sdir, hit = dist[k], surf[k], nrm[k], sdir[k], hit[k]
    share = np.full(S, RING_SHARE)
    share[0] = CENTRE_SHARE
    r = np.where(hit, dist, np.inf)
    cos = np.abs(np.einsum("csk,csk->cs", nrm, sdir))
    rho_cos = refl[surf[:, :, 1]] * cos
    rr = np.where(hit, r, 1.0)
    t2 = wx.transmission2(alpha, rr) if alpha else np.ones_like(rr)
    energy = np.where(hit, share * rho_cos * t2 / (rr * rr), 0.0)
    carla = rho_cos if not atten else rho_cos * np.exp(-float(atten) * rr)
    carla = np.where(hit, share * np.clip(carla, 0.0, 1.0) * t2, 0.0)
    # sort each beam's samples by range; a gap beyond the separation starts an echo
    order = np.argsort(r, axis=1, kind="stable")
    rs = np.take_along_axis(r, order, 1)
    gap = np.zeros((m, S), bool)
    with np.errstate(invalid="ignore"):
        gap[:, 1:] = (rs[:, 1:] - rs[:, :-1]) > sep
    echo = np.cumsum(gap, axis=1)
    ekey = (np.arange(m)[:, None] * S + echo)       # flat (beam, echo) id
    flat = np.zeros((m, S), np.int64)
    np.put_along_axis(flat, order, ekey, 1)          # back in sample order
    fk = flat[hit]
    e_w = energy[hit]
    n_keys = m * S
    E = np.bincount(fk, e_w, n_keys)
    W = np.bincount(fk, share[np.nonzero(hit)[1]], n_keys)
    has = np.bincount(fk, minlength=n_keys) > 0
    RE = np.bincount(fk, e_w * r[hit], n_keys)
    RW = np.bincount(fk, share[np.nonzero(hit)[1]] * r[hit], n_keys)
    with np.errstate(invalid="ignore", divide="ignore"):
        R = np.where(E > 0, RE / np.where(E > 0, E, 1.0), RW / np.where(W > 0, W, 1.0))
    CA = np.bincount(fk, carla[hit], n_keys)
    # the sample that sent the most of each echo (the first such, on a tie): its
    # surface and normal
    samples = np.nonzero(hit.ravel())[0]
    top = np.full(n_keys, -np.inf)
    np.maximum.at(top, fk, e_w)
    at_top = np.nonzero(e_w == top[fk])[0]
    dom = np.full(n_keys, np.iinfo(np.int64).max)
    np.minimum.at(dom, fk[at_top], samples[at_top])
    dom[dom == np.iinfo(np.int64).max] = 0
    centre_key = flat[:, 0]
    contains_centre = np.zeros(n_keys, bool)
    contains_centre[centre_key[hit[:, 0]]] = True
    # detection per echo
    beam_of_key = np.arange(n_keys) // S
    det = _detected(has, E, contains_centre, rays[beam_of_key], np.arange(n_keys) % S,
                    model, detect, key)
    det2 = det.reshape(m, S)
    num = det2.sum(axis=1)
    Em = np.where(det, E, -np.inf).reshape(m, S)
    Rm = np.where(det, R, -np.inf).reshape(m, S)
    strongest = np.argmax(Em, axis=1)
    last = np.argmax(Rm, axis=1)
    rank = np.cumsum(det2, axis=1)                   # echoes are in range order
    mode = beam.return_mode
    primary = last if mode == "last" else strongest
    two = np.zeros(m, bool)
    if mode == "dual":
        # the strongest and the last; when the strongest is the last, the second
        # strongest (as Velodyne's dual return mode does); in range order
        second = np.where(last != strongest, last, np.argmax(
            np.where(np.arange(S) == strongest[:, None], -np.inf, Em), axis=1))
        two = num > 1
        near = np.where(Rm[np.arange(m), second] < Rm[np.arange(m), strongest], second,
                        strongest)
        far = np.where(near == strongest, second, strongest)
        primary = np.where(two, near, strongest)
        last = np.where(two, far, strongest)  # the extra row's echo
    pk = np.arange(m) * S + primary
    extra = np.nonzero(two)[0]
    ek = np.arange(m)[extra] * S + last[extra]
    # mixed points: a reported echo made of more than one object's light
    lo = np.full(n_keys, np.iinfo(np.int64).max)
    hi = np.full(n_keys, -1)
    objects = obj[k][hit].astype(np.int64)  # ufunc.at is ~40x slower when it must cast
    np.minimum.at(lo, fk, objects)
    np.maximum.at(hi, fk, objects)
    d, de = dom[pk], dom[ek]
    return _report(ret, rays, alpha, E, R, CA, num, pk, rank[np.arange(m), primary],
                   surf.reshape(-1, 2)[d], nrm.reshape(-1, 3)[d], lo[pk] != hi[pk],
                   extra, ek, rank[extra, last[extra]], surf.reshape(-1, 2)[de],
                   nrm.reshape(-1, 3)[de], stats)


def _detected(has, E, centre, rays, echo, model, detect, key):
    """Per echo (key): it holds samples and, with a detection model, is detected: the
    echo holding the centre ray with the ray's own uniform (``detect``), the others
    with ``_uniforms`` of (``rays``, ``echo``)."""
    det = has.copy()
    if model is not None:
        u = _uniforms(key, rays, echo)
        if detect is not None:
            u = np.where(centre, detect[rays], u)
        det &= u < model.probability_of(E)
    return det


def _report(ret, rays, alpha, E, R, CA, num, pk, rank_p, surf_p, nrm_p, mixed_p, extra, ek,
            rank_x, surf_x, nrm_x, stats):
    """The reported echoes written into ``ret`` and returned as ``Echoes``: per active
    beam (``rays``) its detected echoes ``num``, its reported echo's key ``pk``, rank,
    surface, normal and whether it is mixed; per second echo (beams ``extra``) its key
    ``ek``, rank, surface and normal. (echoes, stats)."""
    got = num > 0
    Rpk = R[pk]
    t2e = wx.transmission2(alpha, np.where(got, Rpk, 1.0)) if alpha else 1.0
    Rp = np.where(got, Rpk, 1.0)
    prho = E[pk] * Rp * Rp / t2e
    pcar = CA[pk] / t2e
    ret.valid[rays] = got
    sel = np.nonzero(got)[0]
    ret.dist[rays[sel]] = Rpk[sel]
    ret.surface[rays[sel]] = surf_p[sel]
    ret.normals[rays[sel]] = nrm_p[sel]
    n = len(ret.dist)
    Rx = R[ek]
    t2x = wx.transmission2(alpha, Rx) if alpha else 1.0
    rix = np.ones(n + len(extra), np.uint8)
    nret = np.ones(n + len(extra), np.uint8)
    rix[rays[sel]] = rank_p[sel]
    nret[rays[sel]] = num[sel]
    rix[n:] = rank_x
    nret[n:] = num[extra]
    stats.update(footprint_changed_rays=len(rays),
                 multi_echo_rays=int(np.count_nonzero(num > 1)),
                 mixed_points=int(np.count_nonzero(mixed_p[sel])),
                 second_returns=len(extra))
    return Echoes(rays, prho, pcar, rays[extra], Rx, surf_x, nrm_x, E[ek] * Rx ** 2 / t2x,
                  CA[ek] / t2x, rix, nret, stats), stats


def resolve(sub, ret, dirs, skip, refl, model, detect, key, alpha, atten, rmin, rmax):
    """Group each candidate's centre and sub-ray returns into echoes, detect them and
    choose what the device reports (``Echoes``; None when every candidate's sub-rays
    agree with its centre), writing the reported echo of each changed ray into ``ret``;
    (echoes, stats). ``skip``: rows left as they are (ghosts, false returns from the
    air); ``detect``: the frame's detection uniforms (None without a model); ``key``:
    the frame's key for the uniforms of echoes without the centre ray. In C where it is
    built, else ``resolve_numpy``."""
    group = GROUP.get() if compiled else None
    choose = CHOOSE.get() if compiled else None
    if group is None or choose is None:
        return resolve_numpy(sub, ret, dirs, skip, refl, model, detect, key, alpha, atten,
                             rmin, rmax)
    c = np.ascontiguousarray(sub.rows, np.int64)
    n_c, S = len(c), 1 + RING
    stats = {"footprint_rays": int(n_c), "footprint_sub_rays": int(sub.cast)}
    t2 = ex = None
    if alpha or atten:  # the air's exponentials, in numpy (see native/c/echoes.c)
        d = np.concatenate([ret.dist[c][:, None], sub.dist.reshape(n_c, RING)], axis=1)
        with np.errstate(invalid="ignore", over="ignore"):
            t2 = np.ascontiguousarray(wx.transmission2(alpha, d)) if alpha else None
            ex = np.ascontiguousarray(np.exp(-float(atten) * d)) if atten else None
    skipped = None
    if skip is not None and len(skip):
        skipped = np.zeros(len(ret.dist), np.uint8)
        skipped[skip] = 1

    def arr(x, dtype):
        return np.ascontiguousarray(x, dtype)

    keep = [c, arr(ret.dist, np.float64), arr(ret.valid, np.uint8),
            arr(ret.surface, np.int32), arr(ret.normals, np.float64), arr(dirs, np.float64),
            arr(sub.dist, np.float64), arr(sub.tri, np.int64), arr(sub.surface, np.int32),
            arr(sub.normals, np.float64), arr(sub.dirs, np.float64), skipped,
            arr(refl, np.float64), t2, ex]
    beam = np.empty(n_c, np.int64)
    E, R, CA = (np.empty(n_c * S) for _ in range(3))
    dom = np.empty(n_c * S, np.int64)
    has, centre, mixed = (np.empty(n_c * S, np.uint8) for _ in range(3))
    g = _GroupArgs(n_c, *(0 if x is None else x.ctypes.data for x in keep),
                   float(rmin), float(rmax), float(sub.beam.echo_separation_m),
                   CENTRE_SHARE, RING_SHARE, *(x.ctypes.data for x in
                                               (beam, E, R, CA, dom, has, centre, mixed)))
    m = int(group(ctypes.byref(g)))
    if not m:
        return None, stats
    n_keys = m * S
    rays = c[beam[:m]]
    E, R, CA, has = E[:n_keys], R[:n_keys], CA[:n_keys], has[:n_keys].view(bool)
    det = _detected(has, E, centre[:n_keys].view(bool), np.repeat(rays, S),
                    np.tile(np.arange(S), m), model, detect, key)
    primary, second = np.empty(m, np.int64), np.empty(m, np.int64)
    num, two, rank_p, rank_s = (np.empty(m, np.uint8) for _ in range(4))
    surf_p, surf_s = np.empty((m, 2), np.int32), np.empty((m, 2), np.int32)
    nrm_p, nrm_s = np.empty((m, 3)), np.empty((m, 3))
    det8 = det.view(np.uint8)
    ch = _ChooseArgs(m, _MODES[sub.beam.return_mode], det8.ctypes.data,
                     *(x.ctypes.data for x in (primary, second, num, two, rank_p, rank_s,
                                               surf_p, surf_s, nrm_p, nrm_s)))
    choose(ctypes.byref(g), ctypes.byref(ch))
    pk = np.arange(m) * S + primary
    extra = np.nonzero(two)[0]
    return _report(ret, rays, alpha, E, R, CA, num, pk, rank_p, surf_p, nrm_p,
                   mixed[pk].view(bool), extra, extra * S + second[extra], rank_s[extra],
                   surf_s[extra], nrm_s[extra], stats)


class _GroupArgs(ctypes.Structure):
    """``group_t`` of native/c/echoes.c."""

    _fields_ = [("n_c", ctypes.c_int64)] + [
        (name, ctypes.c_void_p) for name in (
            "c", "dist", "valid", "surface", "normal", "dir", "sdist", "stri", "ssurface",
            "snormal", "sdir", "skipped", "refl", "t2", "ex")] + [
        (name, ctypes.c_double) for name in (
            "rmin", "rmax", "sep", "centre_share", "ring_share")] + [
        (name, ctypes.c_void_p) for name in (
            "beam", "E", "R", "CA", "dom", "has", "centre", "mixed")]


class _ChooseArgs(ctypes.Structure):
    """``choose_t`` of native/c/echoes.c."""

    _fields_ = [("m", ctypes.c_int64), ("mode", ctypes.c_int)] + [
        (name, ctypes.c_void_p) for name in (
            "det", "primary", "second", "num", "two", "rank_primary", "rank_second",
            "surface_primary", "surface_second", "normal_primary", "normal_second")]


_MODES = {"strongest": 0, "last": 1, "dual": 2}
# Off: every frame groups and chooses its echoes in numpy (the reference the C code is
# tested against).
compiled = True
NATIVE_ECHOES_ABI = 1
GROUP = Kernel("rls_echo_group", "rls_echoes_abi", NATIVE_ECHOES_ABI,
               [ctypes.POINTER(_GroupArgs)], ctypes.c_int64)
CHOOSE = Kernel("rls_echo_choose", "rls_echoes_abi", NATIVE_ECHOES_ABI,
                [ctypes.POINTER(_GroupArgs), ctypes.POINTER(_ChooseArgs)])

"""Ray casting on Intel Embree 4 through the ``embreex`` wheel (optional dependency).

Same interface as ``casting.NumpyCaster``:

    caster = EmbreeCaster(vertices (V,3) float64, triangles (T,3) int)
    dist, tri = caster.cast(origins (1,3) or (N,3), directions (N,3) unit, max_dist)

``dist`` float64 (inf for a miss), ``tri`` int64 (-1 for a miss). Embree works in
float32; the engine recomputes every range exactly in float64 afterwards
(``casting.refine_hits``), so Embree only decides which triangle a ray hits.

Two ways to drive Embree, chosen automatically (``mode="auto"``):

``packets``  Calls ``rtcIntersect16`` of the Embree library that the ``embreex`` wheel
             bundles (``embree_api``). With RLS's compiled library (``core/native``,
             ``native.library.library_name``; built by ``tools/build_native.py`` for
             each platform's zip, and refused when its interface version is not
             ``embree_loop.NATIVE_ABI``) one ``ctypes`` call casts every ray on its own
             threads without the GIL (``embree_loop``); without it, 16-ray packets laid
             out by numpy go through ``ctypes`` from a thread pool (the GIL changes
             hands every packet, which scales poorly). The packet layout is checked
             once per process by a probe ray before either is trusted.
``embreex``  ``embreex``'s own ``EmbreeScene.run``: one ray at a time in a Cython loop.
             Measured with embreex 4.4.0.post1: it holds the GIL for the whole call,
             so threads do not help and it uses one core.
"""

import ctypes
from collections import deque
from itertools import repeat
import threading

import numpy as np

from ..errors import CastingError, SettingsError
from ..native.threads import default_threads
from ..stop_signals import held
from . import embree_api
from .base import CasterBase
from .embree_api import (_GEOM, _LOCK, _INVALID_ID, _K, _PRIM, _STRIDE, _TFAR, _MotionScene, _Scene,
                         _aligned, _fill, _packet_library)
from .embree_api import available, unavailable_reason  # noqa: F401 (the backend's own questions)
from .embree_loop import _launch, _native_loop

_POOLS = {}


_CHUNK_PACKETS = 2048  # at most 32768 rays per task (3 MiB of packet buffer per thread)


_SERIAL_BELOW = 8192  # small batches (moving objects, re-checks): the pool's handoff costs more


_TASKS_PER_THREAD = 2  # few tasks: each one costs GIL-bound numpy work; 2 per thread balances load


def _pool(threads):
    """A shared thread pool per size (kept for the process: threads are cheap to keep
    and costly to recreate for every frame)."""
    from concurrent.futures import ThreadPoolExecutor

    with _LOCK:
        pool = _POOLS.get(threads)
        if pool is None:
            pool = _POOLS[threads] = ThreadPoolExecutor(threads,
                                                        thread_name_prefix="rls-embree")
        return pool


class EmbreeCaster(CasterBase):
    """Embree 4 (via ``embreex``) closest-hit ray casting; see the module docstring.

    threads  worker threads for packet mode (default: the CPUs this process may use)
    mode     "auto" (packets when the check passes, else embreex), "packets", "embreex"
    """

    name = "embree"

    def __init__(self, vertices, triangles, threads=None, mode="auto", robust=True,
                 native=True):
        v = np.ascontiguousarray(np.asarray(vertices, dtype=np.float64).reshape(-1, 3),
                                 dtype=np.float32)
        t = np.asarray(triangles, dtype=np.int64).reshape(-1, 3)
        self.triangle_count = len(t)
        self.threads = int(threads) if threads else default_threads()
        self.use_native = bool(native)
        lib = _packet_library() if mode in ("auto", "packets") else None
        if mode == "packets" and lib is None:
            raise CastingError(f"Embree packet mode is not usable here ({embree_api.packet_mode_error()})")
        if mode not in ("auto", "packets", "embreex"):
            raise SettingsError(f"unknown Embree mode {mode!r}; choose one of auto, "
                                "packets, embreex")
        self._scene = self._es = None
        if len(t) == 0:
            self.mode = "empty"
        elif lib is not None:
            self.mode = "packets"
            self._scene = _Scene(lib, v, np.ascontiguousarray(t, dtype=np.uint32), robust)
            self._valid = _aligned(_K, np.int32)
            self._valid[:] = -1
            self._local = threading.local()
        else:
            from embreex import rtcore_scene
            from embreex.mesh_construction import TriangleMesh

            self.mode = "embreex"
            self._es = rtcore_scene.EmbreeScene(robust=robust)
            TriangleMesh(self._es, v, np.ascontiguousarray(t, dtype=np.int32))

    @classmethod
    def behind_watertight(cls, vertices, triangles):
        """The build ``casting.WatertightCaster`` casts through: Embree's robust mode
        off. The wrapper re-checks every miss, so robust traversal buys nothing there;
        without it a Pandar64 frame's cast on the benchmark street is ~14% faster
        (robust Embree let 0 of 2M rays aimed at shared edges escape, the fast build
        7.7%, and the wrapper catches them all: tests/blender/test_watertight.py)."""
        return cls(vertices, triangles, robust=False)

    def describe(self):
        threads = self.threads if self.mode == "packets" else 1
        mode = self.mode
        if mode == "packets" and self.use_native and _native_loop() is not None:
            mode = "packets, C loop"
        return f"embree ({mode}, {threads} thread{'s' if threads != 1 else ''})"

    def cast(self, origins, directions, max_dist):
        pending = self._start_native(origins, directions, max_dist, None)
        if pending is not None:
            return pending()[:2]
        d = np.ascontiguousarray(np.asarray(directions, dtype=np.float64).reshape(-1, 3),
                                 dtype=np.float32)
        o = np.asarray(origins, dtype=np.float64).reshape(-1, 3).astype(np.float32)
        n = d.shape[0]
        dist = np.full(n, np.inf)
        tri = np.full(n, -1, dtype=np.int64)
        if n == 0 or self.mode == "empty":
            return dist, tri
        if o.shape[0] not in (1, n):
            raise CastingError("origins must be (1, 3) or one per direction")
        tfar = np.float32(min(float(max_dist), 3.0e38))
        if self.mode == "embreex":
            ob = np.ascontiguousarray(np.broadcast_to(o, d.shape))
            res = self._es.run(ob, d, dists=np.full(n, tfar, np.float32), output=1)
            hit = res["geomID"] != -1
            dist[hit] = res["tfar"][hit]
            tri[hit] = res["primID"][hit]
            return dist, tri
        tasks = max(self.threads * _TASKS_PER_THREAD, -(-n // (_CHUNK_PACKETS * _K)))
        step = min(_CHUNK_PACKETS, max(64, -(-n // (tasks * _K)))) * _K
        spans = [(s, min(n, s + step)) for s in range(0, n, step)]
        work = lambda span: self._cast_span(o, d, tfar, dist, tri, *span)  # noqa: E731
        if len(spans) == 1 or self.threads == 1 or n < _SERIAL_BELOW:
            for span in spans:
                work(span)
        else:
            with held():  # tasks handed over whole (see output.io.behind._background_thread)
                done = _pool(self.threads).map(work, spans)
            list(done)
        return dist, tri

    def cast_refined(self, origins, directions, max_dist, planes, order=None):
        """(dist, tri, unit normals) with every hit refined in float64 against its
        triangle's plane (``planes``: (T, 4) rows nx, ny, nz, n.v0, see
        ``casting.triangle_planes``), fused into the compiled loop; None when the loop
        is not available (the caller then refines in numpy). ``order``: an optional
        permutation of the rays to trace them in (neighbours in it share packets: a
        coherent order is faster); the results are the same."""
        pending = self.start_refined(origins, directions, max_dist, planes, order)
        return None if pending is None else pending()

    def start_refined(self, origins, directions, max_dist, planes, order=None):
        """Start ``cast_refined`` on the compiled loop's own threads and return at once:
        a function that waits and gives its result. Python (and the GIL) is free
        meanwhile. None when the loop is not available."""
        return self._start_native(origins, directions, max_dist, planes, order)

    def native_scene(self):
        """This build's Embree scene handle for the compiled loop, or None when casts
        do not go through the loop (other modes, no loop built)."""
        if self.mode != "packets" or not self.use_native or _native_loop() is None:
            return None
        return self._scene.handle

    def start_rechecked(self, origins, directions, max_dist, planes, order, recheck, keep):
        """``start_refined`` with the watertight re-check of misses (a ``Recheck``)
        done in the loop's threads; ``keep``: what must outlive the cast."""
        if self.native_scene() is None:
            return None
        return _launch(self._scene, self.triangle_count, origins, directions, max_dist,
                       planes, order, threads=self.threads, keep=(self, keep),
                       recheck=recheck)

    def _start_native(self, origins, directions, max_dist, planes, order=None):
        if self.mode != "packets" or not self.use_native:
            return None
        return _launch(self._scene, self.triangle_count, origins, directions, max_dist,
                       planes, order, threads=self.threads, keep=self)

    def _cast_span(self, o, d, tfar, dist, tri, lo, hi):
        buf = getattr(self._local, "buf", None)
        if buf is None:
            buf = self._local.buf = _aligned(_CHUNK_PACKETS * _STRIDE).reshape(-1, _STRIDE)
        m = hi - lo
        p = -(-m // _K)
        b = buf[:p]
        _fill(b, o if o.shape[0] == 1 else o[lo:hi], d[lo:hi], tfar, m)
        fn, valid, scene = self._scene.lib.rtcIntersect16, self._valid.ctypes.data, \
            self._scene.handle
        base = b.ctypes.data
        # One C-level loop: the GIL is held only for ctypes' own call setup.
        deque(map(fn, repeat(valid, p), repeat(scene, p),
                  range(base, base + p * _STRIDE * 4, _STRIDE * 4), repeat(None, p)), 0)
        # Results straight into the caller's arrays, whole packets as (P, 16) views:
        # few temporaries (large ones are page-faulted fresh and slow the threads).
        words = b.view(np.uint32)
        full = m // _K
        if full:
            dv = dist[lo:lo + full * _K].reshape(full, _K)
            tv = tri[lo:lo + full * _K].reshape(full, _K)
            np.copyto(dv, b[:full, _TFAR:_TFAR + _K])
            np.copyto(tv, words[:full, _PRIM:_PRIM + _K], casting="unsafe")
            miss = words[:full, _GEOM:_GEOM + _K] == _INVALID_ID
            dv[miss] = np.inf
            tv[miss] = -1
        rest = m - full * _K
        if rest:
            g = words[full, _GEOM:_GEOM + rest]
            hit = g != _INVALID_ID
            s = lo + full * _K
            dist[s:hi] = np.where(hit, b[full, _TFAR:_TFAR + rest], np.inf)
            tri[s:hi] = np.where(hit, words[full, _PRIM:_PRIM + rest].astype(np.int64), -1)

    def close(self):
        scene, self._scene = self._scene, None
        if scene is not None:
            scene.release()
        self._es = None

    def __del__(self):
        try:
            self.close()
        except Exception:
            pass


_INSTANCING = None  # True/False once checked


class EmbreeInstances:
    """Embree scenes of several ``EmbreeCaster`` s traced together in one traversal,
    each placed by a 4x4 matrix (its triangles' coordinates to the common frame), or
    by matrices at evenly spaced time steps over ray times [0, 1] for an object that
    moves. Embree interpolates between steps linearly, bounds each instance's motion
    and finds the nearest hit over all of them; ``start`` reports for every hit which
    instance it lies in (``placed`` order) and the triangle within it.

    placed  [(caster, matrices (4, 4) or (S, 4, 4), planes or None)]; an instance's
            planes (``casting.triangle_planes`` of its caster's triangles) let the
            compiled loop refine its hits in float64: in the instance's coordinates,
            with the matrix interpolated at the ray's time as Embree does.

    Only with the compiled loop (``usable``); checked once per process by casting at a
    moving probe instance, so a library that lays out instance ids differently is
    never used blindly."""

    def __init__(self, placed):
        if not self.usable(*(c for c, _, _ in placed)):
            raise CastingError("Embree instancing needs the compiled loop and packet mode")
        self.casters = [c for c, _, _ in placed]
        self.threads = max((c.threads for c in self.casters), default=1)
        self._scene = _MotionScene(_packet_library(),
                                   [(c._scene, m) for c, m, _ in placed])
        self._tables = _instance_tables(placed)

    @staticmethod
    def usable(*casters):
        """True when these casters can be instanced (packet mode, compiled loop, and
        the per-process instancing check passed)."""
        if not all(isinstance(c, EmbreeCaster) and c.mode == "packets" and c.use_native
                   for c in casters):
            return False
        return _instancing_works()

    def start(self, origins, directions, max_dist, times=None, order=None, recheck=None):
        """Start the cast: a function giving (dist, tri, normals, instance) per ray
        (instance and tri -1, dist inf for a miss; normals zero where an instance has
        no planes). ``times``: per ray in [0, 1] (None: 0). ``recheck``: (a ``Recheck``
        of the static scene, instance 0, what must outlive it) to re-check the rays
        that do not hit it in the loop's threads (``WatertightCaster.native_recheck``)."""
        rc, keep = recheck if recheck is not None else (None, None)
        got = _launch(self._scene, 0, origins, directions, max_dist, None, order,
                      times=times, instances=self._tables[:3], threads=self.threads,
                      keep=(self, keep), recheck=rc)
        if got is None:
            raise CastingError("the compiled Embree loop could not start")
        return got

    def close(self):
        scene, self._scene = self._scene, None
        if scene is not None:
            scene.release()


EmbreeCaster.instances = EmbreeInstances  # this backend traces moving instances


def _instance_tables(placed):
    """What the compiled loop needs to refine hits on instances ``placed`` [(caster,
    matrices, planes or None)]: (the matrices of every instance as 3x4 rows, per
    instance its first step and step count (0: the identity, no transform), a C array
    of per-instance plane tables, the plane arrays it points into)."""
    mats = [np.asarray(m, np.float64).reshape(-1, 4, 4) for _, m, _ in placed]
    identity = [len(m) == 1 and np.array_equal(m[0], np.eye(4)) for m in mats]
    counts = np.array([0 if i else len(m) for i, m in zip(identity, mats)], np.int64)
    first = np.concatenate([[0], np.cumsum(counts)[:-1]]).astype(np.int64)
    steps = [m[:, :3, :].reshape(-1, 12) for i, m in zip(identity, mats) if not i]
    steps = np.ascontiguousarray(np.concatenate(steps) if steps else np.zeros((1, 12)))
    planes = []
    for c, _, pl in placed:
        if pl is not None:
            pl = np.ascontiguousarray(pl, dtype=np.float64)
            if pl.shape != (c.triangle_count, 4):
                raise CastingError("planes must hold one row per triangle of the instance")
        planes.append(pl)
    planes_of = (ctypes.c_void_p * max(len(placed), 1))(
        *[None if pl is None else pl.ctypes.data for pl in planes])
    return steps, np.ascontiguousarray(np.stack([first, counts], 1)), planes_of, planes


def _instancing_works():
    """Cast at a probe: a unit triangle instanced twice, the second 0.5 m lower and
    moving from x=+10 to x=+20 over ray times [0, 1]; checks instance ids, distances
    (refined in the moving instance's frame) and time."""
    global _INSTANCING
    if _INSTANCING is None:
        ok = False
        try:
            if _packet_library() is not None and _native_loop() is not None:
                tri = EmbreeCaster(np.array([[-1, -1, 0], [3, -1, 0], [-1, 3, 0]], float),
                                   np.array([[0, 1, 2]]))
                move = np.repeat(np.eye(4)[None], 2, axis=0)
                move[0, :3, 3], move[1, :3, 3] = (10, 0, -0.5), (20, 0, -0.5)
                placed = [(tri, np.eye(4), None), (tri, move, None)]
                scene = _MotionScene(_packet_library(), [(c._scene, m) for c, m, _ in placed])
                o = np.array([[0.0, 0, 5], [12.0, 0, 5], [12.0, 0, 5], [50.0, 0, 5]])
                d = np.tile([0.0, 0, -1], (4, 1))
                dist, t, _, inst = _launch(scene, 0, o, d, 100.0, None,
                                           times=np.array([0.0, 0.25, 0.75, 0.0]),
                                           instances=_instance_tables(placed)[:3],
                                           keep=(tri, scene))()
                ok = (list(inst) == [0, 1, -1, -1] and list(t) == [0, 0, -1, -1]
                      and abs(dist[0] - 5) < 1e-5 and abs(dist[1] - 5.5) < 1e-5)
                scene.release()
                tri.close()
        except Exception:  # any surprise: moving objects are cast the portable way
            ok = False
        _INSTANCING = ok
    return _INSTANCING


def packet_mode_error():
    """Why packet mode is not used ('' when it is, or has not been tried yet)."""
    return embree_api.packet_mode_error()

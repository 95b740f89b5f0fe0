"""The compiled Embree loop: ``rls_embree_launch`` / ``rls_embree_finish`` of RLS's
compiled library (``core/native``, ``embree_loop.c``) cast every ray of a batch on
its own threads without the GIL, refine hits in float64 and re-check misses
(``Recheck``). Bound once, after checking its interface version ``NATIVE_ABI``."""

import ctypes
import os
import weakref

import numpy as np

from ..errors import CastingError
from ..native.library import library_path
from .embree_api import _LOCK

_NATIVE = None  # (launch, finish) of the compiled loop in core/native, or False


_NATIVE_ERROR = ""


# The interface version the loop must report (RLS_EMBREE_ABI in native/c/embree_loop.c).
NATIVE_ABI = 4


def load_native(path):
    """(launch, finish) of the compiled loop at ``path``, bound for ctypes; OSError
    when it cannot be loaded or is stale: a build without ``rls_embree_abi`` (older
    than the arguments ``_launch`` passes) or reporting another version than
    ``NATIVE_ABI``. Never calls into a build it has not checked."""
    lib = ctypes.CDLL(path)
    try:
        abi = lib.rls_embree_abi
        start, finish = lib.rls_embree_launch, lib.rls_embree_finish
    except AttributeError as exc:
        raise OSError(f"stale build of the compiled loop ({exc}); rebuild it with "
                      "tools/build_native.py") from None
    abi.restype, abi.argtypes = ctypes.c_int, []
    got = abi()
    if got != NATIVE_ABI:
        raise OSError(f"stale build of the compiled loop (interface {got}, this RLS "
                      f"needs {NATIVE_ABI}); rebuild it with tools/build_native.py")
    vp = ctypes.c_void_p
    args = [vp, vp, vp, ctypes.c_int, vp, vp, ctypes.c_int64, ctypes.c_float,
            vp, vp, vp, vp, vp, ctypes.c_int, vp, vp, vp, vp, ctypes.c_int, vp]
    start.restype, start.argtypes = ctypes.c_void_p, args
    finish.restype, finish.argtypes = None, [ctypes.c_void_p]
    return start, finish


def _native_loop():
    """The compiled packet loop (tools/build_native.py), or None when it is not built
    for this platform, or is stale: then packets are cast from Python on a thread
    pool (the reason in ``native_loop_error``)."""
    global _NATIVE, _NATIVE_ERROR
    with _LOCK:
        if _NATIVE is None:
            path = library_path()
            if not os.path.exists(path):
                _NATIVE, _NATIVE_ERROR = False, (f"no compiled loop for this platform "
                                                 f"({os.path.basename(path)} is missing)")
            else:
                try:
                    _NATIVE = load_native(path)
                except OSError as exc:
                    _NATIVE, _NATIVE_ERROR = False, str(exc)
        return _NATIVE or None


def native_loop_error():
    """Why the compiled loop is not used ('' when it is, or has not been looked for)."""
    return _NATIVE_ERROR


class Recheck(ctypes.Structure):
    """``recheck_t`` of native/c/embree_loop.c: the watertight re-check of misses done in
    the loop's threads (``watertight.WatertightCaster.native_recheck`` fills it;
    ``retried`` comes back). ``static_inst`` -1: a static scene's own cast; else the
    static scene's instance in an instanced cast, re-checked after refinement."""

    _fields_ = [("hull", ctypes.c_void_p), ("boxes", ctypes.c_void_p),
                ("has", ctypes.c_void_p), ("max_dist", ctypes.c_double),
                ("vertices", ctypes.c_void_p), ("triangles", ctypes.c_void_p),
                ("tol", ctypes.c_double), ("nudge", ctypes.c_double),
                ("axis", ctypes.c_double * 3), ("scene", ctypes.c_void_p),
                ("planes", ctypes.c_void_p), ("static_inst", ctypes.c_int32),
                ("use_limit", ctypes.c_int32), ("retried", ctypes.c_int64)]


def _launch(scene, triangle_count, origins, directions, max_dist, planes, order=None,
            times=None, instances=None, threads=1, keep=None, recheck=None):
    """Start a cast of ``scene`` (a ``_Scene`` or ``_MotionScene``) on the compiled
    loop's threads: a ``_Batch`` giving (dist, tri, normals[, instance]), or None
    when the loop is not available. ``planes`` (``triangle_count`` rows) refine hits
    on the scene's own triangles; for a ``_MotionScene`` pass ``instances`` instead
    (``_instance_tables``). ``times`` are per-ray times in [0, 1] for instances with
    motion time steps."""
    native = _native_loop()
    if native is None:
        return None
    start, finish = native
    d = np.ascontiguousarray(directions, dtype=np.float64).reshape(-1, 3)
    o = np.ascontiguousarray(origins, dtype=np.float64).reshape(-1, 3)
    n = d.shape[0]
    if o.shape[0] not in (1, n):
        raise CastingError("origins must be (1, 3) or one per direction")
    pl = None
    if planes is not None:
        pl = np.ascontiguousarray(planes, dtype=np.float64)
        if pl.shape != (triangle_count, 4):
            raise CastingError("planes must hold one (nx, ny, nz, offset) row per triangle")
    if order is not None:
        order = np.ascontiguousarray(order, dtype=np.int64)
        if order.shape != (n,):
            raise CastingError("order must hold one index per ray")
    tm = None
    if times is not None:
        tm = np.ascontiguousarray(np.clip(np.broadcast_to(times, (n,)), 0.0, 1.0),
                                  dtype=np.float32)
    dist = np.empty(n)
    tri = np.empty(n, dtype=np.int64)
    refine = pl is not None or instances is not None
    normals = np.empty((n, 3)) if refine else None
    inst = np.empty(n, dtype=np.int32) if instances is not None else None
    outputs = (dist, tri, normals) + ((inst,) if inst is not None else ())
    if n == 0:
        if refine:
            outputs = (dist, tri, np.zeros((0, 3))) + outputs[3:]
        return lambda: outputs
    tfar = np.float32(min(float(max_dist), 3.0e38))
    ptr = lambda a: None if a is None else a.ctypes.data  # noqa: E731
    steps, info, planes_of = instances if instances is not None else (None, None, None)
    batch = start(ctypes.cast(scene.lib.rtcIntersect16, ctypes.c_void_p).value,
                  scene.handle, o.ctypes.data, int(o.shape[0] == n and n > 1),
                  d.ctypes.data, ptr(order), n, tfar, ptr(tm), ptr(inst), ptr(steps),
                  ptr(info), None if planes_of is None else ctypes.addressof(planes_of),
                  0 if info is None else len(info), ptr(pl),
                  dist.ctypes.data, tri.ctypes.data, ptr(normals),
                  threads, None if recheck is None else ctypes.addressof(recheck))
    if not batch:
        return None
    return _Batch(finish, batch, (keep, scene, o, d, pl, order, tm, instances, recheck),
                  outputs)


# The casts started and not yet collected: ``wait_for_casts`` joins what is left of
# them when a command ends.
_UNDER_WAY = weakref.WeakSet()


def wait_for_casts():
    """Wait for every cast still running on the compiled loop's threads. A stopped run
    drops its cast under way, which waits as it goes (``_Batch.__del__``), but a batch
    kept in a reference cycle (a traceback's frames hold their own exception) goes
    only when the garbage collector finds it, possibly not before the process exits
    and Embree's library is torn down under the running threads. The command line
    calls this when a command ends."""
    for batch in list(_UNDER_WAY):
        batch._wait()


class _Batch:
    """A cast running on the compiled loop's threads. Calling it waits and returns the
    results; the arrays the workers read and write stay referenced until then, and a
    batch dropped without being called still waits (in ``__del__``) before they go."""

    def __init__(self, finish, handle, inputs, outputs):
        self._finish, self._handle = finish, handle
        self._inputs, self._outputs = inputs, outputs
        _UNDER_WAY.add(self)

    def __call__(self):
        self._wait()
        return self._outputs

    def _wait(self):
        handle, self._handle = self._handle, None
        if handle:
            self._finish(handle)
            self._inputs = None

    def __del__(self):
        try:
            self._wait()
        except BaseException:
            # A stop signal taken as the wait began (a handler may raise at any call,
            # this one included): the workers are still joined before the arrays they
            # read and write go with this batch, then the stop goes on (Python drops
            # an exception of __del__; the command line raises the stop again, see
            # core.stop_signals.raise_dropped_stops)
            self._wait()
            raise

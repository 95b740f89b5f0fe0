"""Ray casting on Intel Embree 4 through the ``embreex`` wheel (optional dependency).

Same interface as ``casting.NumpyCaster``:

    caster = EmbreeCaster(vertices (V,3) float64, triangles (T,3) int)
    dist, tri = caster.cast(origins (1,3) or (N,3), directions (N,3) unit, max_dist)

``dist`` float64 (inf for a miss), ``tri`` int64 (-1 for a miss). Embree works in
float32; the engine recomputes every range exactly in float64 afterwards
(``casting.refine_hits``), so Embree only decides which triangle a ray hits.

Two ways to drive Embree, chosen automatically (``mode="auto"``):

``packets``  Calls ``rtcIntersect16`` of the Embree library that the ``embreex`` wheel
             bundles. With the compiled loop (``native/_rls_embree_loop.so``, ``.dll``
             or ``.dylib`` beside this file: ``native_library_name``; built by
             ``tools/build_native.py`` for each platform's zip, and refused when its
             interface version is not ``NATIVE_ABI``) one ``ctypes`` call
             casts every ray on its own threads without the GIL; without it, 16-ray
             packets laid out by numpy go through ``ctypes`` from a thread pool (the
             GIL changes hands every packet, which scales poorly). The packet layout is
             checked once per process by a probe ray before either is trusted.
``embreex``  ``embreex``'s own ``EmbreeScene.run``: one ray at a time in a Cython loop.
             Measured with embreex 4.4.0.post1: it holds the GIL for the whole call,
             so threads do not help and it uses one core.
"""

import ctypes
import glob
from collections import deque
from itertools import repeat
import os
import sys
import threading

import numpy as np

from ..errors import CastingError, SettingsError
from .base import CasterBase

_LOCK = threading.RLock()
_LIB = None          # ctypes handle on libembree4, or False when not usable
_LIB_ERROR = ""
_POOLS = {}

# Embree 4 constants (rtcore_common.h, rtcore_buffer.h, rtcore_geometry.h, rtcore_scene.h).
_GEOMETRY_TYPE_TRIANGLE = 0
_GEOMETRY_TYPE_INSTANCE = 121
_FORMAT_FLOAT3X4_ROW_MAJOR = 0x9134
_MAX_TIME_STEPS = 129  # RTC_MAX_TIME_STEP_COUNT
_BUFFER_TYPE_INDEX = 0
_BUFFER_TYPE_VERTEX = 1
_FORMAT_UINT3 = 0x5003
_FORMAT_FLOAT3 = 0x9003
_SCENE_FLAG_ROBUST = 1 << 2
_INVALID_ID = 0xFFFFFFFF

# RTCRayHit16: structure-of-arrays, 16 lanes each, offsets in 4-byte words.
_K = 16
_ORG, _TNEAR, _DIR, _TIME, _TFAR, _MASK, _ID, _FLAGS = 0, 48, 64, 112, 128, 144, 160, 176
_PRIM, _GEOM, _INST = 272, 288, 304
_STRIDE = 384          # words per packet slot: RTCRayHit16 is 336 words in Embree 4.4
_CHUNK_PACKETS = 2048  # at most 32768 rays per task (3 MiB of packet buffer per thread)
_SERIAL_BELOW = 8192  # small batches (moving objects, re-checks): the pool's handoff costs more
_TASKS_PER_THREAD = 2  # few tasks: each one costs GIL-bound numpy work; 2 per thread balances load


def available():
    """True when the ``embreex`` module can be imported."""
    try:
        import embreex.rtcore_scene  # noqa: F401
    except Exception:  # ImportError, or a broken binary wheel (OSError)
        return False
    return True


def unavailable_reason():
    """Why ``available()`` is False ('' when it is True)."""
    try:
        import embreex.rtcore_scene  # noqa: F401
    except Exception as exc:
        return f"{type(exc).__name__}: {exc}"
    return ""


def default_threads():
    """The CPUs this process may use, or ``RLS_EMBREE_THREADS`` when set (a worker of
    a local cluster gets its share of the cores)."""
    forced = os.environ.get("RLS_EMBREE_THREADS", "").strip()
    if forced.isdigit() and int(forced) > 0:
        return int(forced)
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except AttributeError:  # not Linux
        return max(1, os.cpu_count() or 1)


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


def _find_library():
    """Path of the libembree4 that ``embreex`` loaded (same process, same copy)."""
    import embreex
    import embreex.rtcore_scene  # loads libembree4 into the process

    try:
        with open("/proc/self/maps") as f:
            for line in f:
                if "libembree4" in line or "embree4.so" in line:
                    return line.split(None, 5)[-1].strip()
    except OSError:
        pass
    pkg = os.path.dirname(embreex.__file__)
    site = os.path.dirname(pkg)
    patterns = [os.path.join(site, "embreex.libs", "*embree4*"),
                os.path.join(pkg, ".dylibs", "*embree4*"),
                os.path.join(pkg, "*embree4*")]
    for pat in patterns:
        found = sorted(p for p in glob.glob(pat) if not p.endswith((".pxd", ".py", ".pyi")))
        if found:
            return found[0]
    return None


def _bind(lib):
    vp, u, i, sz = ctypes.c_void_p, ctypes.c_uint, ctypes.c_int, ctypes.c_size_t
    sigs = {
        "rtcNewDevice": (vp, [ctypes.c_char_p]),
        "rtcReleaseDevice": (None, [vp]),
        "rtcGetDeviceError": (i, [vp]),
        "rtcNewScene": (vp, [vp]),
        "rtcSetSceneFlags": (None, [vp, i]),
        "rtcSetSceneBuildQuality": (None, [vp, i]),
        "rtcCommitScene": (None, [vp]),
        "rtcReleaseScene": (None, [vp]),
        "rtcNewGeometry": (vp, [vp, i]),
        "rtcSetNewGeometryBuffer": (vp, [vp, i, u, i, sz, sz]),
        "rtcCommitGeometry": (None, [vp]),
        "rtcAttachGeometry": (u, [vp, vp]),
        "rtcReleaseGeometry": (None, [vp]),
        "rtcIntersect16": (None, [vp, vp, vp, vp]),
        "rtcSetGeometryInstancedScene": (None, [vp, vp]),
        "rtcSetGeometryTimeStepCount": (None, [vp, u]),
        "rtcSetGeometryTransform": (None, [vp, u, i, vp]),
    }
    for name, (res, args) in sigs.items():
        fn = getattr(lib, name)
        fn.restype, fn.argtypes = res, args


_NATIVE = None  # (launch, finish) of the compiled loop next to this file, or False
_NATIVE_ERROR = ""
# The interface version the loop must report (RLS_EMBREE_ABI in native/embree_loop.c).
NATIVE_ABI = 3


def native_library_name(platform=None):
    """File name of the compiled loop for ``platform`` (``sys.platform`` style; default:
    this one): ``_rls_embree_loop`` + .dll on Windows, .dylib on macOS, else .so.
    ``tools/build_native.py`` names its builds with this function."""
    plat = sys.platform if platform is None else platform
    if plat.startswith(("win", "cygwin")):
        ext = ".dll"
    elif plat == "darwin":
        ext = ".dylib"
    else:
        ext = ".so"
    return "_rls_embree_loop" + ext


def native_library_path():
    """Where this platform's compiled loop is looked for: ``native/`` beside this file."""
    return os.path.join(os.path.dirname(os.path.abspath(__file__)), "native",
                        native_library_name())


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
            path = native_library_path()
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


def _aligned(words, dtype=np.float32):
    raw = np.empty(words * 4 + 64, dtype=np.uint8)
    off = (-raw.ctypes.data) % 64
    return raw[off:off + words * 4].view(dtype)


def _packet_library():
    """The checked ctypes handle on libembree4, or None (reason in ``_LIB_ERROR``)."""
    global _LIB, _LIB_ERROR
    with _LOCK:
        if _LIB is None:
            try:
                path = _find_library()
                if not path:
                    raise OSError("libembree4 not found next to embreex")
                lib = ctypes.CDLL(path)
                _bind(lib)
                _probe(lib)
                _LIB = lib
            except Exception as exc:  # any surprise: fall back to embreex's own loop
                _LIB, _LIB_ERROR = False, f"{type(exc).__name__}: {exc}"
        return _LIB or None


def _probe(lib):
    """Cast one packet at a known triangle and check what Embree wrote and where, so
    a library with a different packet layout is never used blindly."""
    scene = _Scene(lib, np.array([[-1, -1, 0], [3, -1, 0], [-1, 3, 0]], np.float32),
                   np.array([[0, 1, 2]], np.uint32))
    try:
        buf = _aligned(2 * _STRIDE).reshape(2, _STRIDE)
        words = buf.view(np.uint32)
        words[:] = 0x7FC0BEEF  # sentinel: a NaN no field would hold
        o = np.zeros((_K, 3), np.float32)
        o[:, 2] = 2.0
        d = np.zeros((_K, 3), np.float32)
        d[:, 2] = -1.0
        d[1, 2] = 1.0  # lane 1 looks away: a miss
        _fill(buf[:1], o, d, 100.0, _K)
        valid = _aligned(_K, np.int32)
        valid[:] = -1
        lib.rtcIntersect16(valid.ctypes.data, scene.handle, buf.ctypes.data, None)
        changed = np.nonzero(words[0] != 0x7FC0BEEF)[0]
        tfar, prim, geom = buf[0, _TFAR:_TFAR + _K], words[0, _PRIM:_PRIM + _K], \
            words[0, _GEOM:_GEOM + _K]
        ok = (abs(tfar[0] - 2.0) < 1e-5 and prim[0] == 0 and geom[0] == 0
              and geom[1] == _INVALID_ID and tfar[1] == np.float32(100.0)
              and changed.max() < _STRIDE and (words[1] == 0x7FC0BEEF).all())
        if not ok:
            raise OSError("Embree packet layout check failed")
    finally:
        scene.release()


def _fill(buf, origins, dirs, max_dist, n):
    """Lay ``n`` rays (padded to whole packets) into packet slots ``buf`` (P, _STRIDE)."""
    p = buf.shape[0]
    words = buf.view(np.uint32)
    pad = p * _K - n
    for k in range(3):
        col = dirs[:, k]
        if pad:
            col = np.concatenate([col, np.full(pad, 1.0 if k == 0 else 0.0, np.float32)])
        buf[:, _DIR + k * _K:_DIR + (k + 1) * _K] = col.reshape(p, _K)
        if origins.shape[0] == 1:
            buf[:, _ORG + k * _K:_ORG + (k + 1) * _K] = origins[0, k]
        else:
            oc = origins[:, k]
            if pad:
                oc = np.concatenate([oc, np.zeros(pad, np.float32)])
            buf[:, _ORG + k * _K:_ORG + (k + 1) * _K] = oc.reshape(p, _K)
    buf[:, _TNEAR:_TNEAR + _K] = 0.0
    buf[:, _TIME:_TIME + _K] = 0.0
    buf[:, _TFAR:_TFAR + _K] = max_dist
    words[:, _MASK:_MASK + _K] = _INVALID_ID  # mask: every bit
    words[:, _ID:_FLAGS + _K] = 0
    words[:, _PRIM:_GEOM + _K] = _INVALID_ID


_DEVICES = {}


def _device(lib):
    """The process's one Embree device (scenes must share a device to instance each
    other); kept for the life of the process."""
    with _LOCK:
        dev = _DEVICES.get(id(lib))
        if dev is None:
            dev = lib.rtcNewDevice(None)
            if not dev:
                raise OSError("rtcNewDevice failed")
            _DEVICES[id(lib)] = dev
        return dev


class _SceneBase:
    """An Embree scene on the shared device, released explicitly."""

    def _open(self, lib):
        self.lib = lib
        self.device = _device(lib)
        self.handle = lib.rtcNewScene(self.device)

    def _attach(self, geom):
        self.lib.rtcCommitGeometry(geom)
        self.lib.rtcAttachGeometry(self.handle, geom)
        self.lib.rtcReleaseGeometry(geom)

    def _commit(self, what):
        self.lib.rtcCommitScene(self.handle)
        err = self.lib.rtcGetDeviceError(self.device)
        if err:
            self.release()
            raise OSError(f"Embree error {err} while building {what}")

    def release(self):
        lib, self.lib = self.lib, None
        if lib is not None and self.handle:
            lib.rtcReleaseScene(self.handle)


class _Scene(_SceneBase):
    """One committed Embree triangle scene."""

    def __init__(self, lib, vertices32, triangles_u32, robust=True, quality=None):
        self._open(lib)
        if robust:
            lib.rtcSetSceneFlags(self.handle, _SCENE_FLAG_ROBUST)
        if quality is not None:  # RTC_BUILD_QUALITY_LOW 0, MEDIUM 1 (default), HIGH 2
            lib.rtcSetSceneBuildQuality(self.handle, int(quality))
        geom = lib.rtcNewGeometry(self.device, _GEOMETRY_TYPE_TRIANGLE)
        vb = lib.rtcSetNewGeometryBuffer(geom, _BUFFER_TYPE_VERTEX, 0, _FORMAT_FLOAT3, 12,
                                         len(vertices32))
        ib = lib.rtcSetNewGeometryBuffer(geom, _BUFFER_TYPE_INDEX, 0, _FORMAT_UINT3, 12,
                                         len(triangles_u32))
        if not vb or not ib:
            lib.rtcReleaseGeometry(geom)
            self.release()
            raise MemoryError("Embree could not allocate the geometry buffers")
        ctypes.memmove(vb, np.ascontiguousarray(vertices32).ctypes.data, vertices32.nbytes)
        ctypes.memmove(ib, np.ascontiguousarray(triangles_u32).ctypes.data, triangles_u32.nbytes)
        self._attach(geom)
        self._commit("the scene")


class _MotionScene(_SceneBase):
    """A top-level Embree scene of instances: each an Embree scene placed by one
    transform, or by transforms at evenly spaced time steps over ray times [0, 1]
    (Embree interpolates the matrices linearly between steps and bounds the motion)."""

    def __init__(self, lib, instances):
        self._open(lib)
        for scene, matrices in instances:
            m = np.ascontiguousarray(np.asarray(matrices, np.float64).reshape(-1, 4, 4)[:, :3, :],
                                     dtype=np.float32)
            if not 1 <= len(m) <= _MAX_TIME_STEPS:
                self.release()
                raise CastingError(f"an instance needs 1 to {_MAX_TIME_STEPS} time steps")
            geom = lib.rtcNewGeometry(self.device, _GEOMETRY_TYPE_INSTANCE)
            lib.rtcSetGeometryInstancedScene(geom, scene.handle)
            lib.rtcSetGeometryTimeStepCount(geom, len(m))
            for k in range(len(m)):
                lib.rtcSetGeometryTransform(geom, k, _FORMAT_FLOAT3X4_ROW_MAJOR, m[k].ctypes.data)
            self._attach(geom)
        self._commit("the instance scene")

    def __del__(self):
        try:
            self.release()
        except Exception:
            pass


class Recheck(ctypes.Structure):
    """``recheck_t`` of native/embree_loop.c: the watertight re-check of misses done in
    the loop's threads (``watertight.WatertightCaster`` fills it; ``retried`` comes
    back)."""

    _fields_ = [("hull", ctypes.c_void_p), ("boxes", ctypes.c_void_p),
                ("has", ctypes.c_void_p), ("max_dist", ctypes.c_double),
                ("vertices", ctypes.c_void_p), ("triangles", ctypes.c_void_p),
                ("tol", ctypes.c_double), ("nudge", ctypes.c_double),
                ("axis", ctypes.c_double * 3), ("retried", ctypes.c_int64)]


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


class _Batch:
    """A cast running on the compiled loop's threads. Calling it waits and returns the
    results; the arrays the workers read and write stay referenced until then, and a
    batch dropped without being called still waits (in ``__del__``) before they go."""

    def __init__(self, finish, handle, inputs, outputs):
        self._finish, self._handle = finish, handle
        self._inputs, self._outputs = inputs, outputs

    def __call__(self):
        self._wait()
        return self._outputs

    def _wait(self):
        handle, self._handle = self._handle, None
        if handle:
            self._finish(handle)
            self._inputs = None

    def __del__(self):
        self._wait()


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
            raise CastingError(f"Embree packet mode is not usable here ({_LIB_ERROR})")
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
            list(_pool(self.threads).map(work, spans))
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

    def start(self, origins, directions, max_dist, times=None, order=None):
        """Start the cast: a function giving (dist, tri, normals, instance) per ray
        (instance and tri -1, dist inf for a miss; normals zero where an instance has
        no planes). ``times``: per ray in [0, 1] (None: 0)."""
        got = _launch(self._scene, 0, origins, directions, max_dist, None, order,
                      times=times, instances=self._tables[:3], threads=self.threads,
                      keep=self)
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
    return _LIB_ERROR

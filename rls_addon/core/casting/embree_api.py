"""Intel Embree 4 through ctypes: the library that the ``embreex`` wheel bundles, its
entry points bound, the packet layout (``RTCRayHit16``) checked by a probe ray before
it is trusted, the process's one device, and committed triangle and instance scenes.

``embree.EmbreeCaster`` casts through these; ``embree_loop`` hands the scenes to the
compiled loop (``core/native``)."""

import ctypes
import glob
import os
import threading

import numpy as np

from ..errors import CastingError
from ..native.kernels import Kernel

_LOCK = threading.RLock()


_LIB = None          # ctypes handle on libembree4, or False when not usable


_LIB_ERROR = ""


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
    (Embree interpolates the matrices linearly between steps and bounds the motion).
    The instances are attached in C where the library is built
    (``native/c/instances.c``: the same Embree calls in the same order), else one
    ctypes call at a time (``_attach_each``, the reference)."""

    def __init__(self, lib, instances):
        self._open(lib)
        mats = [np.asarray(m, np.float64).reshape(-1, 4, 4) for _, m in instances]
        if any(not 1 <= len(m) <= _MAX_TIME_STEPS for m in mats):
            self.release()
            raise CastingError(f"an instance needs 1 to {_MAX_TIME_STEPS} time steps")
        # Every instance's steps as 3x4 float32 rows in one array, handed to Embree (which
        # copies each) by address: a sweep through traffic sets about 900 of them, and a
        # numpy ctypes object per step cost more than the top level's build.
        rows = np.ascontiguousarray(np.concatenate([m[:, :3, :] for m in mats]) if mats
                                    else np.zeros((0, 3, 4)), dtype=np.float32)
        fn = ATTACH_INSTANCES.get() if compiled and instances else None
        if fn is None:
            self._attach_each(instances, mats, rows)
        else:
            scenes = (ctypes.c_void_p * len(instances))(*[sc.handle for sc, _ in instances])
            steps = np.array([len(m) for m in mats], np.int64)
            args = _InstancesArgs(ctypes.addressof(_calls(lib)), self.device, self.handle,
                                  len(instances), ctypes.addressof(scenes),
                                  steps.ctypes.data, rows.ctypes.data)
            if fn(ctypes.byref(args)) != len(instances):
                self.release()
                raise MemoryError("Embree could not make an instance")
        self._commit("the instance scene")

    def _attach_each(self, instances, mats, rows):
        """The instances attached one Embree call at a time (what instances.c does)."""
        lib = self.lib
        address, size = rows.ctypes.data, rows[0].nbytes if len(rows) else 0
        set_transform = lib.rtcSetGeometryTransform
        first = 0
        for (scene, _), m in zip(instances, mats):
            geom = lib.rtcNewGeometry(self.device, _GEOMETRY_TYPE_INSTANCE)
            lib.rtcSetGeometryInstancedScene(geom, scene.handle)
            lib.rtcSetGeometryTimeStepCount(geom, len(m))
            for k in range(len(m)):
                set_transform(geom, k, _FORMAT_FLOAT3X4_ROW_MAJOR, address + size * (first + k))
            first += len(m)
            self._attach(geom)

    def __del__(self):
        try:
            self.release()
        except Exception:
            pass


def packet_mode_error():
    """Why packet mode is not used ('' when it is, or has not been tried yet)."""
    return _LIB_ERROR


# The Embree entry points instances.c calls, in the order of its embree_calls_t.
_CALLS = ("rtcNewGeometry", "rtcSetGeometryInstancedScene", "rtcSetGeometryTimeStepCount",
          "rtcSetGeometryTransform", "rtcCommitGeometry", "rtcAttachGeometry",
          "rtcReleaseGeometry")


class _EmbreeCalls(ctypes.Structure):
    """``embree_calls_t`` of native/c/instances.c."""

    _fields_ = [(name, ctypes.c_void_p) for name in _CALLS]


class _InstancesArgs(ctypes.Structure):
    """``instances_t`` of native/c/instances.c."""

    _fields_ = [("calls", ctypes.c_void_p), ("device", ctypes.c_void_p),
                ("scene", ctypes.c_void_p), ("count", ctypes.c_int64),
                ("scenes", ctypes.c_void_p), ("steps", ctypes.c_void_p),
                ("rows", ctypes.c_void_p)]


_CALL_TABLES = {}


def _calls(lib):
    """The entry points of ``lib`` that instances.c calls (kept for the process)."""
    with _LOCK:
        got = _CALL_TABLES.get(id(lib))
        if got is None:
            got = _CALL_TABLES[id(lib)] = _EmbreeCalls(
                *[ctypes.cast(getattr(lib, name), ctypes.c_void_p).value for name in _CALLS])
        return got


NATIVE_INSTANCES_ABI = 1
ATTACH_INSTANCES = Kernel("rls_attach_instances", "rls_instances_abi", NATIVE_INSTANCES_ABI,
                          [ctypes.POINTER(_InstancesArgs)], ctypes.c_int64)
# Off: instances are attached one ctypes call at a time (the reference instances.c
# follows).
compiled = True

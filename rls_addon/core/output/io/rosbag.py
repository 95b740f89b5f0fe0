"""A ROS 2 bag (MCAP storage) of one scan run, written with ``rosbags`` (imported when
the bag is opened).

The bag is a directory ``NAME/`` holding ``metadata.yaml`` and ``NAME.mcap``. It is
written under a temporary name beside it and renamed on ``close``; an exception (or
``abort``) removes it, so the bag is complete or absent.

Topics (``<sensor>`` is the sensor's name made a valid ROS name, ``ros_name``):

    /<sensor>/points  sensor_msgs/msg/PointCloud2, one per sensor per frame: the points
                      in the sensor frame, fields and types of the bag's point type
                      (``point_types``), height 1, width N, point_step = the record size,
                      row_step = N * point_step, little endian, is_dense when every
                      coordinate is finite; header.frame_id = <sensor>, header.stamp =
                      the frame's stamp
    /tf_static        tf2_msgs/msg/TFMessage: <world> -> <sensor> of every still sensor,
                      all of them in each message (as tf2's static broadcaster latches
                      them), written when a still sensor first appears; offered QoS
                      reliable, transient local, keep last 1
    /tf               tf2_msgs/msg/TFMessage: <world> -> <sensor> of each moving sensor
                      at every frame's stamp

Stamps: frame f of a scene starting at ``start_time_s`` (e.g. Unix seconds) is stamped
``start_time_s + (f - first_frame) / fps`` (``frame_stamp_ns``), the start of its sweep.
"""

import decimal
import fractions
import os
import pathlib
import re
import shutil
import tempfile

import numpy as np

from ....version import VERSION
from ...errors import OutputError, RLSError, SettingsError
from ...points import POINT_DTYPE
from .point_types import DEFAULT_POINT_TYPE, to_point_type
from .point_types import point_type as _layout

POINTS_TYPE = "sensor_msgs/msg/PointCloud2"
TF_TYPE = "tf2_msgs/msg/TFMessage"
# PointField datatypes (sensor_msgs/msg/PointField.msg) of little-endian numpy types
POINT_FIELD_TYPES = {"i1": 1, "u1": 2, "<i2": 3, "<u2": 4, "<i4": 5, "<u4": 6, "<f4": 7, "<f8": 8}
_NAME_BAD = re.compile(r"[^A-Za-z0-9_]")
RIGID_TOLERANCE = 1e-6  # a pose's 3x3 must be a rotation within this (no scale, no shear)
STILL_TOLERANCE = 1e-9  # a still sensor's pose may not change by more (m, and per entry)


def _rosbags():
    try:
        from rosbags.interfaces import (
            Qos,
            QosDurability,
            QosHistory,
            QosLiveliness,
            QosReliability,
            QosTime,
        )
        from rosbags.rosbag2 import StoragePlugin, Writer
        from rosbags.typesys import Stores, get_typestore
    except ImportError:
        raise RLSError("writing ROS 2 bags needs the Python package rosbags: "
                       "pip install rosbags==0.11.9 (into Blender's Python: "
                       "<blender>/python/bin/python -m pip install rosbags==0.11.9)") from None
    latched = Qos(QosHistory.KEEP_LAST, 1, QosReliability.RELIABLE,
                  QosDurability.TRANSIENT_LOCAL, QosTime(0, 0), QosTime(0, 0),
                  QosLiveliness.AUTOMATIC, QosTime(0, 0), False)
    return Writer, StoragePlugin, get_typestore(Stores.ROS2_JAZZY), latched


def ros_name(name):
    """``name`` as a ROS name token (topic part and frame id): letters, digits and single
    underscores (ROS 2 reserves '__'), not starting with a digit."""
    token = re.sub("_+", "_", _NAME_BAD.sub("_", str(name).strip())) or "_"
    return f"_{token}" if token[0].isdigit() else token


def frame_stamp_ns(start_time_s, frame, first_frame, fps):
    """Integer nanoseconds of frame ``frame``'s stamp: ``start_time_s`` (s) at
    ``first_frame`` (a finite number: ``OutputSettings`` checks), plus (frame -
    first_frame) / fps. ``SettingsError`` when it is not a bag's stamp (unsigned 64-bit
    nanoseconds: from 1970 to 2554)."""
    if not fps > 0:
        raise SettingsError(f"frame rate must be positive, got {fps!r}")
    # the start as written (shortest decimal of the float): 1.7e9 s is 1.7e18 ns, which a
    # float64 holds only to 256 ns
    start_ns = int((decimal.Decimal(repr(float(start_time_s))) * 10**9).to_integral_value(
        decimal.ROUND_HALF_EVEN))
    offset = fractions.Fraction(int(frame) - int(first_frame)) * 10**9 / fractions.Fraction(fps)
    stamp = start_ns + round(offset)
    if not 0 <= stamp < 2 ** 64:
        raise SettingsError(
            f"a ROS 2 bag's stamps are unsigned nanoseconds, from 0 (1970) to "
            f"{decimal.Decimal(2 ** 64 - 1) / 10 ** 9} s: frame {frame} would be stamped "
            f"{float(decimal.Decimal(stamp) / 10 ** 9):g} s; give a start time "
            "(--start-time) that puts every frame in that span")
    return stamp


def rigid_transform(matrix):
    """(translation (3,), quaternion (4,) as x y z w) of a 4x4 rigid sensor-to-world
    pose; ``OutputError`` when its 3x3 is not a rotation (scale, shear, mirror)."""
    m = np.asarray(matrix, dtype=np.float64).reshape(4, 4)
    r = m[:3, :3]
    if not np.all(np.isfinite(m)) or np.abs(r.T @ r - np.eye(3)).max() > RIGID_TOLERANCE \
            or np.linalg.det(r) < 0:
        raise OutputError("a sensor pose for TF must be a rotation and a translation (no "
                          "scale, shear or mirror): apply the LiDAR object's scale")
    return m[:3, 3].copy(), quaternion(r)


def quaternion(r):
    """Unit quaternion (x, y, z, w), w >= 0, of a 3x3 rotation matrix."""
    r = np.asarray(r, dtype=np.float64)
    # four candidate magnitudes; the largest is computed from the diagonal stably
    q2 = np.array([1 + r[0, 0] - r[1, 1] - r[2, 2], 1 - r[0, 0] + r[1, 1] - r[2, 2],
                   1 - r[0, 0] - r[1, 1] + r[2, 2], 1 + r[0, 0] + r[1, 1] + r[2, 2]]) / 4
    k = int(np.argmax(q2))
    big = np.sqrt(q2[k])
    s = 1 / (4 * big)
    off = {  # q_i q_j products from the off-diagonal entries
        0: (big, (r[0, 1] + r[1, 0]) * s, (r[0, 2] + r[2, 0]) * s, (r[2, 1] - r[1, 2]) * s),
        1: ((r[0, 1] + r[1, 0]) * s, big, (r[1, 2] + r[2, 1]) * s, (r[0, 2] - r[2, 0]) * s),
        2: ((r[0, 2] + r[2, 0]) * s, (r[1, 2] + r[2, 1]) * s, big, (r[1, 0] - r[0, 1]) * s),
        3: ((r[2, 1] - r[1, 2]) * s, (r[0, 2] - r[2, 0]) * s, (r[1, 0] - r[0, 1]) * s, big),
    }[k]
    q = np.array(off)
    q /= np.linalg.norm(q)
    return -q if q[3] < 0 else q


def point_fields(dtype):
    """(name, offset, PointField datatype, count) of a packed little-endian structured
    dtype, in its order."""
    out = []
    for name in dtype.names:
        sub, offset = dtype.fields[name][:2]
        key = sub.base.str.replace("|", "")
        if key not in POINT_FIELD_TYPES:
            raise OutputError(f"field {name} has type {sub.base}, which PointCloud2 cannot hold")
        out.append((name, int(offset), POINT_FIELD_TYPES[key], int(np.prod(sub.shape) or 1)))
    return out


class BagWriter:
    """A ROS 2 bag of one run: open once, ``write`` each (sensor, frame) cloud as it comes,
    ``close`` at the end (or use it as a context manager, which aborts on an exception).

    path         the bag directory to create (``NAME``; its file is ``NAME/NAME.mcap``)
    point_type   the layout of the clouds (``point_types.POINT_TYPES``), default 'rls'
    world_frame  TF parent frame of every sensor (default 'map')
    overwrite    replace an existing bag at ``path`` on close (else OutputError now)
    """

    def __init__(self, path, *, point_type=DEFAULT_POINT_TYPE, world_frame="map", overwrite=False):
        self.path = pathlib.Path(path)
        self.layout = _layout(point_type)
        self.world_frame = ros_name(world_frame)
        self.overwrite = bool(overwrite)
        if self.path.exists() and not self.overwrite:
            raise OutputError(f"{self.path} already exists; pass --overwrite to replace it")
        if self.path.exists() and not self.path.is_dir():
            raise OutputError(f"cannot write bag {self.path}: a file is in the way")
        writer_cls, plugin, self._types, self._latched = _rosbags()
        self._connections = {}
        self._sensors = {}  # sensor -> (ros name, moving, still pose or None)
        self._static = {}   # ros name -> TransformStamped of the still sensors
        self._writer, self._closed = None, False
        try:
            self.path.parent.mkdir(parents=True, exist_ok=True)
            self._tmp = pathlib.Path(tempfile.mkdtemp(prefix=f".{self.path.name}.", suffix=".tmp",
                                                      dir=self.path.parent))
        except OSError as exc:
            raise OutputError(f"cannot write bag {self.path}: {exc.strerror or exc}") from None
        self._bag = self._tmp / self.path.name
        try:
            self._writer = writer_cls(self._bag, version=9, storage_plugin=plugin.MCAP)
            self._writer.open()
            self._writer.set_custom_data("rls.point_type", self.layout.name)
            self._writer.set_custom_data("rls.world_frame", self.world_frame)
            self._writer.set_custom_data("rls.software", f"rls {VERSION}")
        except OSError as exc:
            self.abort()
            raise self._cannot(exc) from None
        except BaseException:
            self.abort()
            raise

    def _cannot(self, exc, frame=None):
        """The ``OutputError`` of an ``OSError`` (a full disk, a lost mount) while the
        bag is written; the bag is dropped."""
        where = "" if frame is None else f" (frame {frame})"
        return OutputError(f"cannot write bag {self.path}: {exc.strerror or exc}{where}; "
                           "no bag was left")

    # -- messages -----------------------------------------------------------------------

    def _stamp(self, stamp_ns):
        t = self._types.types["builtin_interfaces/msg/Time"]
        ns = int(stamp_ns)
        return t(sec=ns // 1_000_000_000, nanosec=ns % 1_000_000_000)

    def _header(self, stamp_ns, frame_id):
        return self._types.types["std_msgs/msg/Header"](stamp=self._stamp(stamp_ns),
                                                        frame_id=frame_id)

    def _cloud(self, stamp_ns, frame_id, records):
        T = self._types.types
        fields = [T["sensor_msgs/msg/PointField"](name=n, offset=o, datatype=d, count=c)
                  for n, o, d, c in point_fields(records.dtype)]
        n = len(records)
        step = records.dtype.itemsize
        xyz = [records[f] for f in ("x", "y", "z") if f in records.dtype.names]
        dense = bool(all(np.isfinite(c).all() for c in xyz))
        data = np.frombuffer(np.ascontiguousarray(records).tobytes(), dtype=np.uint8)
        return T[POINTS_TYPE](header=self._header(stamp_ns, frame_id), height=1, width=n,
                              fields=fields, is_bigendian=False, point_step=step,
                              row_step=n * step, data=data, is_dense=dense)

    def _transform(self, stamp_ns, child, pose):
        T = self._types.types
        (tx, ty, tz), (qx, qy, qz, qw) = rigid_transform(pose)
        tf = T["geometry_msgs/msg/Transform"](
            translation=T["geometry_msgs/msg/Vector3"](x=float(tx), y=float(ty), z=float(tz)),
            rotation=T["geometry_msgs/msg/Quaternion"](x=float(qx), y=float(qy), z=float(qz),
                                                       w=float(qw)))
        return T["geometry_msgs/msg/TransformStamped"](
            header=self._header(stamp_ns, self.world_frame), child_frame_id=child, transform=tf)

    def _put(self, topic, msgtype, stamp_ns, msg, qos=()):
        conn = self._connections.get(topic)
        if conn is None:
            conn = self._writer.add_connection(topic, msgtype, typestore=self._types,
                                               offered_qos_profiles=qos)
            self._connections[topic] = conn
        self._writer.write(conn, int(stamp_ns), self._types.serialize_cdr(msg, msgtype))

    # -- the run's interface -------------------------------------------------------------

    def write(self, sensor, frame, stamp_ns, records, sensor_to_world, moving):
        """Add ``sensor``'s cloud of ``frame`` (int, named in errors) stamped
        ``stamp_ns`` (int ns, ``frame_stamp_ns``).

        records          (N,) in the sensor frame: already in the bag's point type, or
                         ``POINT_DTYPE`` points, converted here with the stamp as the
                         sweep's start
        sensor_to_world  4x4 rigid pose of the sensor at the stamp
        moving           False: the sensor stands still for the whole run (/tf_static,
                         once); True: its pose goes to /tf every frame
        """
        if self._closed:
            raise OutputError(f"bag {self.path} is already closed")
        try:
            self._write(sensor, stamp_ns, records, sensor_to_world, bool(moving))
        except OutputError as exc:
            self.abort()
            raise OutputError(f"{exc} (frame {frame}; bag {self.path} not written)") from None
        except OSError as exc:
            self.abort()
            raise self._cannot(exc, frame) from None
        except BaseException:
            self.abort()
            raise

    def _write(self, sensor, stamp_ns, records, pose, moving):
        records = np.asarray(records)
        if records.dtype == POINT_DTYPE:
            records = to_point_type(records, self.layout.name, start_time_s=int(stamp_ns) * 1e-9)
        if records.dtype != self.layout.dtype:
            raise OutputError(f"{sensor}: records of {records.dtype} are not the bag's point "
                              f"type '{self.layout.name}'")
        name, pose = self._register(sensor, pose, moving)
        if moving:
            tf = self._transform(stamp_ns, name, pose)
            self._put("/tf", TF_TYPE, stamp_ns, self._types.types[TF_TYPE](transforms=[tf]))
        elif name not in self._static:
            self._static[name] = self._transform(stamp_ns, name, pose)
            msg = self._types.types[TF_TYPE](transforms=list(self._static.values()))
            self._put("/tf_static", TF_TYPE, stamp_ns, msg, qos=[self._latched])
        self._put(f"/{name}/points", POINTS_TYPE, stamp_ns, self._cloud(stamp_ns, name, records))

    def _register(self, sensor, pose, moving):
        pose = np.asarray(pose, dtype=np.float64).reshape(4, 4)
        known = self._sensors.get(sensor)
        if known is None:
            name = ros_name(sensor)
            if any(n == name for n, _, _ in self._sensors.values()):
                raise OutputError(f"sensors {sensor!r} and another both become ROS name {name!r}")
            self._sensors[sensor] = (name, moving, None if moving else pose.copy())
            return name, pose
        name, was_moving, still = known
        if was_moving != moving:
            raise OutputError(f"{sensor} is moving in some frames and still in others: a "
                              "sensor's TF is either static or per frame for the whole bag")
        if not moving and np.abs(pose - still).max() > STILL_TOLERANCE:
            raise OutputError(f"{sensor} was written as still but its pose changed")
        return name, pose

    def close(self):
        """Finish the bag and move it to ``path``; returns the path."""
        if self._closed:
            return self.path
        try:
            self._writer.close()
            self._closed = True
            self._publish()
        except OSError as exc:
            self.abort()
            raise self._cannot(exc) from None
        except BaseException:
            self.abort()
            raise
        return self.path

    def _publish(self):
        old = None
        try:
            if self.path.exists():
                if not self.overwrite:
                    raise OutputError(f"{self.path} already exists; pass --overwrite to replace it")
                old = self._tmp / ".replaced"
                os.rename(self.path, old)
            os.rename(self._bag, self.path)
        except OSError as exc:
            if old is not None and not self.path.exists():
                os.rename(old, self.path)  # put the earlier bag back
            raise OutputError(f"cannot write bag {self.path}: {exc.strerror or exc}") from None
        shutil.rmtree(self._tmp, ignore_errors=True)

    def abort(self):
        """Drop the bag: nothing is left at ``path`` (an earlier bag there is kept)."""
        self._closed = True
        try:
            if self._writer is not None and self._writer.storage is not None:
                self._writer.close()
        except Exception:  # noqa: BLE001, S110 - the bag is dropped; its close may fail too
            pass
        shutil.rmtree(self._tmp, ignore_errors=True)

    def __enter__(self):
        return self

    def __exit__(self, exc_type, exc, tb):
        if exc_type is None:
            self.close()
        else:
            self.abort()
        return False


__all__ = [
    "POINT_FIELD_TYPES",
    "BagWriter",
    "frame_stamp_ns",
    "point_fields",
    "quaternion",
    "rigid_transform",
    "ros_name",
]

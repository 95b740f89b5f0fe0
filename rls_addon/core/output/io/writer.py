"""Writing a scan run's files.

``CloudWriter``: one file per (sensor, frame) in the sensor's format (PCD, PLY with its
fields or a driver's point type; LAS in world coordinates), and the JSON sidecar
beside it. ``BagWriter``: one ROS 2 bag (MCAP) per run. Both atomic (complete or
absent), checked before the first scan; clouds are resumable.
"""

import os

from ....version import VERSION
from ...errors import OutputError, RLSError, SettingsError
from ...labels import DEFAULT_LABELS
from .sidecar import points_to_world
from .atomic import atomic_write_bytes, writable_folder
from .behind import WRITES_BEHIND, WritesBehind  # noqa: F401 - WRITES_BEHIND: the bound
from .cloud import parts_writer, read_records, record_parts, write_cloud
from .paths import output_path, sanitize_name
from .point_types import to_point_type
from .sidecar import read_sidecar, settings_differences, sidecar_path, write_sidecar


class CloudWriter:
    """Files of one run of scene ``scene_name``. ``output`` arguments are a sensor's
    ``settings.OutputSettings`` with an absolute (or working-directory relative)
    ``directory``.

    overwrite  replace existing files (else an existing file is an error)
    resume     an existing output whose cloud reads back and matches its sidecar is
               kept (``existing``); others are replaced"""

    shardable = True  # a run's pieces may write on several workers

    def __init__(self, scene_name, overwrite=False, resume=False, sensors=(), preview=False,
                 background=False):
        self.scene_name = scene_name
        self.overwrite, self.resume = bool(overwrite), bool(resume)
        self.preview = bool(preview)  # also a picture of each cloud (pictures.py)
        # LAS point source ids: 1..K in the order of the whole run's sensors (the same
        # in every piece of a run spread over workers)
        self.sensors = tuple(sensors)
        # background: each scan's files are written behind the scan (``behind``)
        self.background = bool(background)
        self._behind = WritesBehind(background)

    @property
    def _pending(self):
        """The background writes under way."""
        return self._behind.pending

    def path(self, sensor, output, frame):
        return output_path(output.directory, output.template, scene=self.scene_name,
                           sensor=sensor, frame=frame, fmt=output.format)

    def planned_files(self, sensor, output, frame):
        """Every file a scan of (sensor, frame) writes."""
        path = self.path(sensor, output, frame)
        return [path, sidecar_path(path)] + ([picture_path(path)] if self.preview else [])

    def incomplete(self, sensor, output, frame):
        """Files of (sensor, frame) that a write cut short (a killed process) left: a
        cloud without its sidecar."""
        path = self.path(sensor, output, frame)
        return [path] if os.path.isfile(path) and not sidecar_path(path).exists() else []

    def check(self, sensor, output, frame):
        """Fail now, before anything is scanned, when ``sensor``'s files cannot be
        written: the folder, the template and the format are checked."""
        if output.format == "mcap":
            raise SettingsError("a ROS 2 bag holds a whole run: write it with BagWriter "
                                "(rls scan --format mcap)")
        writable_folder(output.directory)
        self.path(sensor, output, frame)
        if output.format == "las":
            self._las(output)  # laspy (and pyproj for a CRS) present, settings valid
        if self.preview:
            from ..pictures import _plt

            _plt()

    def existing(self, sensor, output, frame, settings=None):
        """The point count of a finished earlier output (when resuming), else None: the
        cloud must read back, and its sidecar must exist and name the same sensor,
        frame and point count, and state the same ``settings`` (the run's
        ``session.settings_record``; with the output's format, fields and point type)."""
        if not self.resume:
            return None
        path = self.path(sensor, output, frame)
        if not os.path.isfile(path):
            return None
        try:
            info = read_sidecar(path)
            if not info or info.get("sensor") != sensor or info.get("frame") != frame:
                return None
            if settings is not None and settings_differences(info, self._record(output, settings)):
                return None
            n = _count(path)
        except (RLSError, OSError, ValueError):
            return None
        return n if info.get("points") == n else None

    def stale_settings(self, sensor, output, frame, settings):
        """The names of the settings an earlier output of (sensor, frame) was written
        with otherwise than ``settings`` say (empty: the same, or no such output)."""
        path = self.path(sensor, output, frame)
        try:
            info = read_sidecar(path) if os.path.isfile(path) else None
        except RLSError:
            return []
        return settings_differences(info, self._record(output, settings)) if info else []

    @staticmethod
    def _record(output, settings):
        rec = dict(settings, format=output.format, point_type=output.point_type)
        if output.format != "las" and output.point_type == "rls":
            rec["fields"] = list(output.fields)
        return rec

    def orphans(self, planned):
        """Clouds of another format beside the outputs of ``planned`` [(sensor, output,
        frame)] (an earlier run in another format): the same name but the extension.
        One listing per folder."""
        from .fields import FORMAT_EXT

        exts = {e for e in FORMAT_EXT.values() if e}
        names = {}
        for sensor, output, frame in planned:
            p = self.path(sensor, output, frame)
            names.setdefault(os.path.dirname(os.path.abspath(p)), set()).add(os.path.basename(p))
        found = []
        for folder, mine in names.items():
            stems = {os.path.splitext(n)[0] for n in mine}
            try:
                entries = os.listdir(folder)
            except OSError:
                continue
            for e in entries:
                stem, ext = os.path.splitext(e)
                if ext.lower() in exts and stem in stems and e not in mine:
                    found.append(os.path.join(folder, e))
        return sorted(found)

    def flush(self):
        """Wait for every background write under way; raises what the first that failed
        raised (after all of them ended)."""
        self._behind.flush()

    def finish(self, run):
        """Write the run's instance table once per output folder:
        ``<scene>_instances.json`` (stable instance id -> object and label), merged
        with the table of an earlier run into the same folder (resumed runs)."""
        import json

        from .atomic import atomic_write_bytes

        self.flush()
        table = run.instance_table()
        folders = sorted({j.settings.output.directory for j in run.sensors})
        for folder in folders:
            path = os.path.join(folder, f"{sanitize_name(self.scene_name)}_instances.json")
            merged = {}
            if os.path.isfile(path):
                try:
                    with open(path, encoding="utf-8") as fh:
                        merged = json.load(fh).get("instances", {})
                except (OSError, ValueError):
                    merged = {}
            merged.update(table)
            body = {"scene": self.scene_name, "instances": dict(sorted(merged.items(),
                                                                        key=lambda kv: int(kv[0]))),
                    "label_names": {str(k): v for k, v in DEFAULT_LABELS.items()}}
            atomic_write_bytes(path, (json.dumps(body, indent=2) + "\n").encode("utf-8"),
                               overwrite=True)

    def write(self, sensor, output, frame, points, info):
        """Write the cloud (only ``output.fields``) and its sidecar; returns the cloud's
        path. Interrupted between the two, the cloud goes again: no cloud is left
        without its sidecar. ``background``: started, after the previous write ended
        (``points`` and ``info`` must not change meanwhile)."""
        path = self.path(sensor, output, frame)
        self._behind.run(self._write, path, sensor, output, points, info)
        return path

    def _write(self, path, sensor, output, points, info):
        existed = os.path.exists(path)
        # resuming replaces what it scans again, a sidecar left by a cloud of another
        # format included
        overwrite = self.overwrite or (self.resume and (existed or sidecar_path(path).exists()))
        fields = list(output.fields)
        try:
            if output.format == "las":
                self._las(output, overwrite, sensor).write(
                    path, sensor, points_to_world(points, info, str(path)),
                    info.get("timestamp_s", 0.0))
                fields = ["x", "y", "z", "intensity", "gps_time", "classification",
                          "point_source_id", "ring", "label", "instance", "ghost"]
            elif output.point_type != "rls":
                records = to_point_type(points, output.point_type,
                                        start_time_s=info.get("timestamp_s", 0.0),
                                        channel_elevations_deg=info.get("channel_elevations_deg"))
                atomic_write_bytes(path, parts_writer(record_parts(records, output.format)),
                                   overwrite=overwrite)
                fields = list(records.dtype.names)
            else:
                write_cloud(path, points, fmt=output.format, fields=output.fields,
                            overwrite=overwrite)
            write_sidecar(path, dict(info, format=output.format, fields=fields,
                                     point_type=output.point_type,
                                     software=f"rls {VERSION}"), overwrite=overwrite)
            if self.preview:
                from ..pictures import cloud_picture

                atomic_write_bytes(picture_path(path), cloud_picture(points, info),
                                   overwrite=True)
        except BaseException:
            if not existed and os.path.isfile(path) and not sidecar_path(path).exists():
                try:
                    os.unlink(path)
                except OSError:
                    pass
            raise
        return path

    def _las(self, output, overwrite=False, sensor="sensor"):
        from .las import LasWriter

        names = self.sensors if sensor in self.sensors else self.sensors + (sensor,)
        return LasWriter(names, offset=output.las_offset, crs=output.crs, overwrite=overwrite)

    def abort(self):
        """A run ended early: every file written is complete (the write under way ends
        first), nothing to drop."""
        self.flush()


def picture_path(cloud_path):
    """Where a cloud's picture goes: beside it, ``.png``."""
    import pathlib

    return pathlib.Path(cloud_path).with_suffix(".png")


def _count(path):
    """Points in a cloud file: PCD and PLY read back; LAS from its header."""
    if str(path).lower().endswith(".las"):
        from .las import _laspy

        with _laspy().open(str(path)) as las:
            return int(las.header.point_count)
    return len(read_records(path))


class BagWriter:
    """The scan run's writer of one ROS 2 bag (MCAP storage, ``io.rosbag``) for the
    whole run: ``<folder>/<scene>_rosbag2/``, the sensors' clouds (sensor frame, the
    output's point type) on ``/<sensor>/points``, their poses on ``/tf_static`` or
    ``/tf``, stamped ``start_time_s + (frame - first frame) / fps``. Written under a
    temporary name and renamed when the run ends; a run that stops early leaves no bag
    (``abort``). A bag is not resumable and a run that writes one is not split over
    workers (``shardable``)."""

    shardable = False
    per_scan = False  # one file for every scan of the run

    def __init__(self, scene_name, folder, point_type="rls", fps=24.0, first_frame=1,
                 start_time_s=0.0, overwrite=False, resume=False):
        if resume:
            raise SettingsError("a ROS 2 bag cannot be resumed: run it again with --overwrite")
        self.scene_name, self.folder = scene_name, folder
        self.point_type, self.fps, self.first_frame = point_type, float(fps), int(first_frame)
        self.start_time_s = float(start_time_s)
        self.overwrite, self.resume = bool(overwrite), False
        self.bag = None

    @property
    def bag_path(self):
        return os.path.join(self.folder, f"{sanitize_name(self.scene_name)}_rosbag2")

    def path(self, sensor, output, frame):
        return self.bag_path

    def planned_files(self, sensor, output, frame):
        return [self.bag_path]

    def check(self, sensor, output, frame):
        if output.format != "mcap":
            raise SettingsError("a run writes one bag for all its LiDARs: give every LiDAR "
                                "the format 'mcap' (rls scan --format mcap)")
        writable_folder(self.folder)
        if os.path.exists(self.bag_path) and not self.overwrite:
            raise OutputError(f"{self.bag_path} already exists; pass --overwrite to replace it")
        from . import rosbag

        rosbag._rosbags()  # the library is there
        # the run's first frame has a bag stamp (later ones are checked as written)
        rosbag.frame_stamp_ns(self.start_time_s, frame, self.first_frame, self.fps)

    def existing(self, sensor, output, frame, settings=None):
        return None

    def write(self, sensor, output, frame, points, info):
        from . import rosbag

        if info.get("frame_space") != "sensor":
            raise SettingsError("a bag holds sensor-frame clouds: scan with the sensor frame "
                                "(--frame-space sensor)")
        if self.bag is None:
            self.bag = rosbag.BagWriter(self.bag_path, point_type=self.point_type,
                                        overwrite=self.overwrite)
        stamp = rosbag.frame_stamp_ns(self.start_time_s, frame, self.first_frame, self.fps)
        records = to_point_type(points, self.point_type, start_time_s=stamp * 1e-9,
                                channel_elevations_deg=info.get("channel_elevations_deg"))
        self.bag.write(sensor, frame, stamp, records, info["sensor_pose_start"],
                       bool(info.get("sensor_moves")))
        return self.bag_path

    def finish(self, run):
        if self.bag is not None:
            self.bag.close()

    def abort(self):
        if self.bag is not None:
            self.bag.abort()

    def flush(self):
        """Every message is in the bag as it is written: nothing to wait for."""


def make_writer(jobs, scene_name, fps, first_frame, overwrite=False, resume=False,
                preview=False, background=False):
    """The writer of a run of ``jobs`` (``run.SensorJob``): a ``BagWriter`` when their
    format is 'mcap' (one bag for all, in the first LiDAR's folder), else a
    ``CloudWriter`` (writing in the ``background``, see there)."""
    bags = [j for j in jobs if j.settings.output.format == "mcap"]
    if not bags:
        return CloudWriter(scene_name, overwrite, resume, sensors=[j.name for j in jobs],
                           preview=preview, background=background)
    if len(bags) != len(jobs):
        raise SettingsError("a run writes one bag for all its LiDARs: give every LiDAR the "
                            "format 'mcap' (rls scan --format mcap), or none")
    moving_frames = [j.name for j in bags if j.settings.scan.frame_space != "sensor"]
    if moving_frames:
        raise SettingsError(f"a bag holds sensor-frame clouds (TF gives their poses): set the "
                            f"Frame of {', '.join(moving_frames)} to Sensor "
                            f"(--frame-space sensor)")
    out = bags[0].settings.output
    return BagWriter(scene_name, out.directory, out.point_type, fps, first_frame,
                     out.start_time_s, overwrite, resume)


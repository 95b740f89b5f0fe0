"""Writing a scan run as one ROS 2 bag (the output format 'mcap'): ``BagWriter``, the
scan run's writer (``run.Writer``) over ``rosbag.BagWriter``, and ``run_writer``, the
format's entry point (``formats.FORMATS``)."""

import os

from ...errors import OutputError, SettingsError
from .atomic import writable_folder
from .names import sanitize_name
from .point_types import to_point_type


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


def run_writer(jobs, scene_name, fps, first_frame, overwrite=False, resume=False):
    """The ``BagWriter`` of a run of ``jobs`` (every one in this format): one bag for
    all, in the first LiDAR's folder."""
    out = jobs[0].settings.output
    return BagWriter(scene_name, out.directory, out.point_type, fps, first_frame,
                     out.start_time_s, overwrite, resume)

"""Writing a scan run's files: one cloud per (sensor, frame) in the sensor's format
with its fields, and the JSON sidecar beside it. Atomic (a cloud is complete or
absent), checked before the first scan, and resumable."""

import os

from ...version import VERSION
from ..errors import RLSError
from .atomic import writable_folder
from .cloud import read_cloud, write_cloud
from ..labels import DEFAULT_LABELS
from .paths import output_path, sanitize_name
from .sidecar import read_sidecar, sidecar_path, write_sidecar


class CloudWriter:
    """Files of one run of scene ``scene_name``. ``output`` arguments are a sensor's
    ``settings.OutputSettings`` with an absolute (or working-directory relative)
    ``directory``.

    overwrite  replace existing files (else an existing file is an error)
    resume     an existing output whose cloud reads back and matches its sidecar is
               kept (``existing``); others are replaced"""

    def __init__(self, scene_name, overwrite=False, resume=False):
        self.scene_name = scene_name
        self.overwrite, self.resume = bool(overwrite), bool(resume)

    def path(self, sensor, output, frame):
        return output_path(output.directory, output.template, scene=self.scene_name,
                           sensor=sensor, frame=frame, fmt=output.format)

    def planned_files(self, sensor, output, frame):
        """Every file a scan of (sensor, frame) writes."""
        path = self.path(sensor, output, frame)
        return [path, sidecar_path(path)]

    def check(self, sensor, output, frame):
        """Fail now, before anything is scanned, when ``sensor``'s files cannot be
        written: the folder, the template and the format are checked."""
        writable_folder(output.directory)
        self.path(sensor, output, frame)

    def existing(self, sensor, output, frame):
        """The point count of a finished earlier output (when resuming), else None: the
        cloud must read back, and its sidecar must exist and name the same sensor,
        frame and point count."""
        if not self.resume:
            return None
        path = self.path(sensor, output, frame)
        if not os.path.isfile(path):
            return None
        try:
            info = read_sidecar(path)
            if not info or info.get("sensor") != sensor or info.get("frame") != frame:
                return None
            n = len(read_cloud(path))
        except (RLSError, OSError, ValueError):
            return None
        return n if info.get("points") == n else None

    def finish(self, run):
        """Write the run's instance table once per output folder:
        ``<scene>_instances.json`` (stable instance id -> object and label), merged
        with the table of an earlier run into the same folder (resumed runs)."""
        import json

        from .atomic import atomic_write_bytes

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
        without its sidecar."""
        path = self.path(sensor, output, frame)
        existed = os.path.exists(path)
        overwrite = self.overwrite or (self.resume and existed)
        try:
            write_cloud(path, points, fmt=output.format, fields=output.fields,
                        overwrite=overwrite)
            write_sidecar(path, dict(info, format=output.format, fields=list(output.fields),
                                     software=f"rls {VERSION}"), overwrite=overwrite)
        except BaseException:
            if not existed and os.path.isfile(path) and not sidecar_path(path).exists():
                try:
                    os.unlink(path)
                except OSError:
                    pass
            raise
        return path

"""Writing a scan run's files.

``CloudWriter``: one file per (sensor, frame) in the sensor's format (its entry in
``formats.FORMATS`` writes it: PCD, PLY with its fields or a driver's point type; LAS
in world coordinates), and the JSON sidecar beside it; atomic (complete or absent),
checked before the first scan, resumable. ``make_writer`` chooses it, or the run writer
of a format written once per run (``bag_writer``: one ROS 2 bag).
"""

import json
import os

from ....version import VERSION
from ...choices import FRAME_SPACES
from ...errors import OutputError, RLSError, SettingsError
from ...labels import DEFAULT_LABELS
from .atomic import atomic_write_bytes, writable_folder
from .behind import WRITES_BEHIND, WritesBehind  # noqa: F401 - WRITES_BEHIND: the bound
from .formats import FORMATS, Cloud
from .names import sanitize_name
from .paths import output_path
from .sidecar import read_sidecar, settings_differences, sidecar_path, write_sidecar


def _cloud_extensions():
    """The extensions of the formats written a file per scan ('.pcd', '.ply', '.las')."""
    return {f.extension for f in FORMATS if f.extension}


def _other_format_cloud(path):
    """The cloud beside ``path`` that its sidecar describes when that is a cloud of
    another format (an earlier run's, under the same name), else None (``preview``:
    the picture is not asked about, so that cloud is all it can give)."""
    got = _described_leftovers(path, preview=True)
    return got[0] if got else None


def _described_leftovers(path, preview):
    """Files of an earlier run beside ``path`` that its sidecar, about to be replaced,
    describes and that this write does not replace: a cloud of another format ('x.pcd'
    and 'x.ply' share 'x.json'), and the picture (``picture_path``) an earlier run
    drew with --preview-png when this one draws none (``preview`` False). Only the
    files the sidecar names: nothing else beside it is touched (a picture from before
    sidecars named theirs is left). The sidecar is read only when such a file is there
    (a run with --overwrite asks for every frame)."""
    candidates = [path.with_suffix(e) for e in _cloud_extensions() if e != path.suffix.lower()]
    picture = None if preview else picture_path(path)
    if not any(p.is_file() for p in candidates + ([picture] if picture else [])):
        return []
    try:
        old = json.loads(sidecar_path(path).read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return []
    if not isinstance(old, dict):
        return []
    out = []
    fmt = old.get("format")
    ext = FORMATS.get(fmt).extension if isinstance(fmt, str) and fmt in FORMATS else ""
    if ext and ext != path.suffix.lower() and path.with_suffix(ext).is_file():
        out.append(path.with_suffix(ext))
    if picture is not None and old.get("picture") == picture.name and picture.is_file():
        out.append(picture)
    return out


def _remove_replaced(leftover, path):
    what = ("the picture of an earlier run with --preview-png"
            if leftover.suffix.lower() not in _cloud_extensions()
            else "the earlier cloud of the same frame in another format")
    try:
        os.unlink(leftover)
    except FileNotFoundError:
        pass
    except OSError as exc:
        raise OutputError(f"wrote {path.name}, but cannot remove {leftover}, {what}, which "
                          f"its sidecar no longer describes ({exc.strerror or exc}); remove "
                          f"it by hand") from None


class CloudWriter:
    """Files of one run of scene ``scene_name``. ``output`` arguments are a sensor's
    ``settings.OutputSettings`` with an absolute (or working-directory relative)
    ``directory``.

    overwrite  replace existing files (else an existing file is an error)
    resume     an existing output whose cloud reads back and matches its sidecar is
               kept (``existing``); others are replaced"""

    shardable = True  # a run's pieces may write on several workers
    written_at_end = "the run's table of objects (<scene>_instances.json) is"  # finish
    # every write goes through ``WritesBehind.run``: a scan may leave values of its info
    # to be worked out there (``behind.Later``)
    works_out_later = True

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
        fmt = FORMATS.get(output.format)
        if fmt.run_writer is not None:
            raise SettingsError(f"the format '{fmt.id}' ({fmt.label}) holds a whole run, not a "
                                f"file per scan: write it with its run writer (make_writer; "
                                f"rls scan --format {fmt.id})")
        writable_folder(output.directory)
        self.path(sensor, output, frame)
        if fmt.check is not None:
            fmt.check(output)  # its library present, its settings valid
        if self.preview:
            from ..pictures import _plt

            _plt()

    def existing(self, sensor, output, frame, settings=None):
        """The point count of a finished earlier output (when resuming), else None: the
        cloud must read back, and its sidecar must exist and name the same sensor,
        frame and point count, and state the same ``settings`` (the run's
        ``session.settings_record``; with the output's format, fields and point type);
        a run with --preview-png also wants the picture that sidecar names."""
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
            picture = picture_path(path)
            if self.preview and not (info.get("picture") == picture.name and picture.is_file()):
                return None
            count = FORMATS.get(output.format).count
            if count is None:  # a format that cannot count its files is scanned again
                return None
            n = count(path)
        except (RLSError, OSError, ValueError):
            return None
        return n if info.get("points") == n else None

    def kept_labels(self, sensor, output, frame):
        """The ``labels`` of the sidecar of an output ``existing`` kept (its objects, for
        the run's instance table: a run that kept every frame, after a stop that came
        between the last write and the table, wrote an empty one)."""
        labels = read_sidecar(self.path(sensor, output, frame)).get("labels", {})
        return labels if isinstance(labels, dict) else {}

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
        if FORMATS.get(output.format).encode is not None and output.point_type == "rls":
            rec["fields"] = list(output.fields)
        return rec

    def orphan_notices(self, planned):
        """What a run says of the clouds of another format beside the outputs of
        ``planned`` [(sensor, output, frame)] (an earlier run in another format: the
        same name but the extension; one listing per folder): those described by the
        sidecars this run replaces are removed as their frames are written
        (``_write``), others are left as they are."""
        exts = _cloud_extensions()
        names = {}
        for sensor, output, frame in planned:
            p = self.path(sensor, output, frame)
            names.setdefault(os.path.dirname(os.path.abspath(p)), {})[os.path.basename(p)] = p
        replaced, left = [], []
        for folder, mine in names.items():
            stems = {os.path.splitext(n)[0]: p for n, p in mine.items()}
            try:
                entries = os.listdir(folder)
            except OSError:
                continue
            for e in entries:
                stem, ext = os.path.splitext(e)
                if ext.lower() in exts and stem in stems and e not in mine:
                    other = os.path.join(folder, e)
                    ours = stems[stem]
                    described = _other_format_cloud(ours) == ours.with_suffix(ext)
                    (replaced if described else left).append(other)
        out = []
        for files, what in ((sorted(replaced), "an earlier run's clouds of these frames, "
                             "described by the sidecars this run replaces (the formats "
                             "share them): each is removed once its frame's new files are "
                             "written"),
                            (sorted(left), "left as they are (no sidecar here describes "
                             "them)")):
            if files:
                kinds = ", ".join(sorted({os.path.splitext(f)[1] for f in files}))
                out.append(f"{len(files)} file(s) of another format ({kinds}) beside this "
                           f"run's outputs, e.g. {files[0]}: {what}")
        return out

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
        # what the sidecar about to be replaced describes and this write does not
        # replace (a cloud in another format, a picture): removed once this frame's
        # files are in place, so no file is left that no sidecar describes
        replaced = _described_leftovers(path, self.preview) if overwrite else []
        drawn = {"picture": picture_path(path).name} if self.preview else {}
        try:
            fields = FORMATS.get(output.format).write(
                Cloud(path, sensor, points, info, output, overwrite, self.sensors))
            write_sidecar(path, dict(info, format=output.format, fields=fields,
                                     point_type=output.point_type, **drawn,
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
        for leftover in replaced:
            _remove_replaced(leftover, path)
        return path

    def abort(self):
        """A run ended early: every file written is complete (the write under way ends
        first), nothing to drop."""
        self.flush()


def picture_path(cloud_path):
    """Where a cloud's picture goes: beside it, ``.png``."""
    import pathlib

    return pathlib.Path(cloud_path).with_suffix(".png")


def make_writer(jobs, scene_name, fps, first_frame, overwrite=False, resume=False,
                preview=False, background=False):
    """The writer of a run of ``jobs`` (``run.SensorJob``): the run writer of their
    format when it is one written once per run (a ROS 2 bag: one for all, in the first
    LiDAR's folder), else a ``CloudWriter`` (writing in the ``background``, see there)."""
    formats = [FORMATS.get(j.settings.output.format) for j in jobs]
    whole = [f for f in formats if f.run_writer is not None]
    if not whole:
        return CloudWriter(scene_name, overwrite, resume, sensors=[j.name for j in jobs],
                           preview=preview, background=background)
    fmt = whole[0]
    if len(whole) != len(jobs) or any(f is not fmt for f in whole):
        raise SettingsError(f"a run writes one {fmt.label} for all its LiDARs: give every "
                            f"LiDAR the format '{fmt.id}' (rls scan --format {fmt.id}), or none")
    if fmt.frame_space is not None:
        others = [j.name for j in jobs if j.settings.scan.frame_space != fmt.frame_space]
        if others:
            raise SettingsError(f"{fmt.label} holds {fmt.frame_space}-frame clouds: set the "
                                f"Frame of {', '.join(others)} to "
                                f"{FRAME_SPACES.label(fmt.frame_space)} "
                                f"(--frame-space {fmt.frame_space})")
    return fmt.run_writer(jobs, scene_name, fps, first_frame, overwrite, resume)

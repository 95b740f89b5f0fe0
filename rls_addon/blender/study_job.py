"""The Study panel's study as a job of small steps (the operator runs one per timer
event, so Blender stays responsive; scripts run them all): the panel's properties
become the same ``StudyConfig`` ``rls study`` makes (``study_config``, the one place),
the core's ``StudyRun`` reads the scene and scans one candidate per step, then the
search, the charts, the report files (when an output folder is set) and the answer
in the scene (``study_answer.show_answer``). Nothing is made in the scene before the
last step, so a job stopped earlier leaves the scene as it was (its frame put back)."""

import os
import time

import bpy

from ..core.casting import caster_factory
from ..core.errors import OutputError, SceneError
from ..core.study.config import study_config as core_study_config
from ..core.study.loop import StudyRun
from ..core.study.report import charts_png, report_clash, write_report
from .read_rules import is_rls_helper
from .region import is_lob
from .scenes.build import is_mount
from .study import BlenderStudyScene
from .study_answer import show_answer
from .values import typed_float

# What the panel calls the settings typed as text (for the errors)
FIELD_LABELS = {"k": "Sensors (k)", "grid_heights": "Grid Heights", "pitches": "Pitches",
                "yaws": "Yaws", "traffic_frames": "Traffic Frames",
                "evaluate_frames": "Evaluate Frames"}


def mount_names(scene, props, selected):
    """The mounts the panel asks for, as ``StudyConfig.mounts``: the objects marked as
    mounts (listed by name when a grid is added, since no names means the grid
    alone), the selected objects, or none (the grid alone)."""
    if props.mounts_from == "SELECTED":
        names = sorted(o.name for o in selected if not is_rls_helper(o) and not is_lob(o))
        if not names:
            raise SceneError("no mount selected: select the objects the LiDARs would sit "
                             "on (poles, walls, ...), or study the marked mounts")
        return tuple(names)
    if props.mounts_from == "NONE":
        if not props.use_grid:
            raise SceneError("no candidates: choose mounts, or turn the grid on")
        return ()
    if props.use_grid:
        return tuple(sorted(o.name for o in scene.objects if is_mount(o)))
    return ()


def study_config(scene, props, lob_name, selected=()):
    """The ``StudyConfig`` of the Study panel's properties (``Scene.rls_study``) over the
    region ``lob_name``: what ``rls study`` makes of the same settings as flags (lengths
    as typed: ``values.typed_float``)."""
    return core_study_config(
        names=FIELD_LABELS, device=props.device_id, k=props.k, lob=lob_name,
        mounts=mount_names(scene, props, selected),
        grid_step=typed_float(props.grid_step) if props.use_grid else None,
        grid_heights=props.grid_heights, grid_margin=typed_float(props.grid_margin),
        pitches=props.pitches, yaws=props.yaws, yaw_mode=props.yaw_mode,
        roll=typed_float(props.roll), labels=props.labels, disks=int(props.disks),
        radius=typed_float(props.radius), disk_seed=int(props.disk_seed),
        disk_placement=props.disk_placement, cell=typed_float(props.cell),
        scan_seed=int(props.seed), noise=bool(props.noise), dropout=bool(props.dropout),
        keep_traffic=bool(props.keep_traffic), backend=props.backend,
        one_per_mount=not props.shared_mounts, exhaustive_limit=int(props.exhaustive_limit),
        traffic_frames=props.traffic, evaluate_frames=props.evaluate,
        evaluate_min_points=int(props.min_points))


def output_folder(path, ks, overwrite):
    """The absolute report folder of the panel's ``path`` (None: no files), refused
    before any scan when it cannot be written or holds a report (without
    ``overwrite``)."""
    if not path or not path.strip():
        return None
    if path.startswith("//") and not bpy.data.filepath:
        raise OutputError(f"output folder '{path}' is relative to the .blend file, which is "
                          "not saved yet: save the file or choose an absolute folder")
    folder = os.path.normpath(bpy.path.abspath(path))
    if os.path.exists(folder) and not os.path.isdir(folder):
        raise OutputError(f"cannot write the report to {folder}: it is a file")
    parent = folder if os.path.isdir(folder) else os.path.dirname(folder)
    if not os.path.isdir(parent) or not os.access(parent, os.W_OK):
        raise OutputError(f"cannot write the report to {folder}: {parent} is not a "
                          "writable folder")
    clash = None if overwrite else report_clash(folder, ks)
    if clash:
        raise OutputError(f"{clash} already exists: turn on Overwrite to replace the report")
    return folder


class StudyJob:
    """One study of ``cfg`` over ``scene`` in steps: ``step()`` until ``finished``,
    ``finish()`` in any case (puts the scene's frame back). It answers as a core
    ``ScanRun`` does to the operators' modal loop (``operators.running.ModalRun``):
    ``total`` and ``index`` (the progress bar, in thousandths), ``status()``,
    ``cancelled`` (the next step ends it, with nothing made), ``run()``."""

    total = 1000

    STAGES = ("read", "scan", "search", "charts", "answer")

    def __init__(self, scene, cfg, out_dir=None, overwrite=False, factory=caster_factory):
        self.scene, self.cfg, self.factory = scene, cfg, factory
        self.out_dir = output_folder(out_dir, cfg.k, overwrite)
        self.overwrite = overwrite
        self.frame0 = scene.frame_current
        self.stage = "read"
        self.study = self.result = self.charts = self.summary = self.made = None
        self.finished = self.cancelled = False
        self.eta = None
        self.notices = []
        self.t0 = time.perf_counter()

    def _progress(self, done, total, cand, eta):
        self.eta = eta

    def step(self):
        """Do the next step; ``finished`` after the last (or at once when cancelled)."""
        if self.cancelled:
            self.finished = True
        elif self.stage == "read":
            self.study = StudyRun(BlenderStudyScene(self.scene), self.cfg, self._progress,
                                self.factory)
            self.stage = "scan"
        elif self.stage == "scan":
            self.study.step()
            if self.study.scanned_all:
                self.stage = "search"
        elif self.stage == "search":
            self.result = self.study.finish()
            self.notices.extend(self.result.notices)
            self.stage = "charts"
        elif self.stage == "charts":
            self.charts = charts_png(self.result)
            if self.charts[1]:
                self.notices.append(self.charts[1])
            self.stage = "answer"
        elif self.stage == "answer":
            if self.out_dir is not None:
                self.summary = write_report(self.result, self.out_dir, self.overwrite,
                                            charts=self.charts)
            self.made = show_answer(self.scene, self.result, self.charts[0])
            self.finished = True

    def run(self, interrupt_cancels=False):
        """Every step; Ctrl-C cancels when ``interrupt_cancels`` (nothing made)."""
        try:
            while not self.finished:
                self.step()
        except KeyboardInterrupt:
            if not interrupt_cancels:
                raise
            self.cancelled = self.finished = True

    @property
    def index(self):
        return int(self.total * self.fraction())

    def fraction(self):
        """How far the job is, 0..1 (the scans are most of it)."""
        if self.finished:
            return 1.0
        if self.stage == "read":
            return 0.0
        if self.stage == "scan":
            return 0.02 + 0.88 * self.study.done / max(self.study.total, 1)
        return {"search": 0.9, "charts": 0.94, "answer": 0.98}[self.stage]

    def status(self):
        """The status bar's text."""
        if self.stage == "read":
            return "RLS study: reading the scene and building its ray-casting structure"
        if self.stage == "scan":
            left = f", about {self.eta:.0f} s left" if self.eta is not None else ""
            return (f"RLS study: scanning candidate {self.study.done + 1} of {self.study.total}"
                    f"{left} (Esc to stop)")
        if self.stage == "search":
            return "RLS study: searching the sets of each k"
        if self.stage == "charts":
            return "RLS study: drawing the charts"
        return "RLS study: putting the answer in the scene"

    def finish(self):
        if self.scene.frame_current != self.frame0:
            self.scene.frame_set(self.frame0)

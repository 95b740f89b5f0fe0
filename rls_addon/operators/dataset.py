"""*File > Export > RLS Dataset*: the scene's LiDARs over a frame range written as a
KITTI/OpenPCDet or OPV2V dataset, with ground truth: the same settings object and run
as ``rls dataset`` (``DatasetSettings``, ``blender.dataset.dataset_run``), so the same
files. Modal from the UI with a progress bar and Esc (``ModalRun``)."""

import bpy
from bpy.props import BoolProperty, EnumProperty, FloatProperty, IntProperty, StringProperty

from ..blender import batch
from ..blender.dataset import dataset_run
from ..blender.sensor import is_lidar
from ..core.errors import OutputExists, RLSError
from ..core.output.datasets import LAYOUTS
from ..core.output.datasets.settings import DEFAULT_CLASSES, DatasetSettings
from ..core.scan.background_sweeps import run_all
from .common import _poll_any_lidar, status_text
from .running import ModalRun, report_run


def frames_of(scene, use_scene_range, start, end, step):
    """The frames an operator's range options give (the scene's range, or its own)."""
    if use_scene_range:
        start, end, step = scene.frame_start, scene.frame_end, scene.frame_step
    if end < start:
        raise RLSError(f"empty frame range {start}-{end}")
    return list(range(start, end + 1, max(1, step)))


class RLS_OT_export_dataset(ModalRun, bpy.types.Operator):
    """Scan a frame range with the scene's LiDARs into a dataset detectors train on
    (KITTI/OpenPCDet or OPV2V), with ground-truth boxes: what rls dataset writes"""

    bl_idname = "rls.export_dataset"
    bl_label = "Export RLS Dataset"
    bl_options = {"REGISTER"}

    directory: StringProperty(subtype="DIR_PATH", description="The dataset folder")
    filter_folder: BoolProperty(default=True, options={"HIDDEN"},
                                description="Show folders in the file browser")
    from_ui: BoolProperty(default=False, options={"HIDDEN", "SKIP_SAVE"},
                          description="Chosen in the file browser: run with a progress bar")
    layout: EnumProperty(name="Layout", items=LAYOUTS.items(), default="kitti",
                         description="The dataset layout")
    use_scene_range: BoolProperty(name="Scene Frame Range", default=True,
                                  description="Export the scene's frame range (else Start to End)")
    frame_start: IntProperty(name="Start", default=1, description="First frame")
    frame_end: IntProperty(name="End", default=1, description="Last frame")
    frame_step: IntProperty(name="Step", default=1, min=1, description="Every Nth frame")
    selected_only: BoolProperty(name="Selected LiDARs Only", default=False,
                                description="Only the selected LiDARs (else every LiDAR)")
    classes: StringProperty(name="Classes", default=DEFAULT_CLASSES,
                            description="Labels whose objects get boxes (names or ids, comma "
                                        "separated)")
    use_seed: BoolProperty(name="Seed", default=False,
                           description="One seed for every LiDAR (else each LiDAR's own)")
    seed: IntProperty(name="Seed", default=0, min=0, description="The seed of every LiDAR")
    intensity: EnumProperty(name="Intensity", items=[("0-1", "0 to 1", "Intensity 0-1"),
                                                     ("0-255", "0 to 255", "Intensity 0-255")],
                            description="kitti: the scale of the points' intensity")
    points_format: EnumProperty(name="Points", items=[
        ("npy", "npy", "What OpenPCDet's custom dataset loader reads"),
        ("bin", "bin", "Raw float32 x, y, z, intensity")],
        description="kitti: the points' file format")
    level: BoolProperty(name="Level", default=False,
                        description="kitti: points and boxes in a gravity-aligned frame at "
                                    "each sensor (its yaw kept), as OpenPCDet assumes")
    min_points: IntProperty(name="Min Points", default=1, min=0,
                            description="kitti: leave boxes with fewer points out of the labels")
    val_share: FloatProperty(name="Validation Share", default=0.2, min=0.0, max=0.99,
                             description="kitti: share of frames for ImageSets/val.txt")
    split_seed: IntProperty(name="Split Seed", default=0, min=0,
                            description="kitti: the seed that draws the validation frames")
    overwrite: BoolProperty(name="Overwrite", default=False,
                            description="Replace files of an earlier export")
    resume: BoolProperty(name="Resume", default=False,
                         description="Keep complete frames of an earlier export, scan the rest")

    poll = classmethod(_poll_any_lidar)
    _writer = None

    def settings(self, context):
        """The ``DatasetSettings`` of these options: what ``rls dataset`` builds from
        its flags."""
        if not self.directory:
            raise RLSError("Choose the dataset folder")
        sensors = ()
        if self.selected_only:
            sensors = tuple(sorted(o.name for o in context.selected_objects if is_lidar(o)))
            if not sensors:
                raise RLSError("No LiDAR is selected: select some, or export every LiDAR")
        return DatasetSettings(
            layout=self.layout, out=bpy.path.abspath(self.directory),
            frames=frames_of(context.scene, self.use_scene_range, self.frame_start,
                             self.frame_end, self.frame_step),
            sensors=sensors, classes=self.classes, seed=self.seed if self.use_seed else None,
            intensity=self.intensity, points_format=self.points_format, level=self.level,
            min_points=self.min_points, split_seed=self.split_seed,
            val_share=round(self.val_share, 6),  # a float32 property: 0.2, not 0.2000000029
            overwrite=self.overwrite, resume=self.resume)

    def _make_run(self, context):
        batch.clear_cancel()
        try:
            run, self._writer, (sweeps, _, notices) = dataset_run(
                context.scene, self.settings(context), cancelled=batch.cancel_requested)
        except OutputExists as exc:
            raise RLSError(f"{exc.paths[0]} already exists (an earlier export's): tick "
                           "Resume to keep its complete frames or Overwrite to replace "
                           "them, or choose another folder") from None
        for notice in run.notices + notices:
            self.report({"INFO"}, notice)
        if sweeps:  # a few scans of the scene without road users, before the frames
            status_text(context, f"Export: {len(sweeps)} background sweeps of the scene "
                                 "without road users")
            try:
                run_all(sweeps)
            finally:
                status_text(context, None)
        return run

    def _report(self, run):
        later = getattr(self._writer, "written_at_end", None)
        result = report_run(self, run, what="Export",
                            later=later and f"The dataset's own files: {later} written once "
                                            "every frame is done; export again with Resume "
                                            "ticked to finish")
        for notice in getattr(self._writer, "notices", []):
            self.report({"INFO"}, notice)
        if result == {"FINISHED"}:
            if self.layout == "kitti":  # what Detect and Evaluate runs over next
                bpy.context.scene.rls.evaluation.dataset = str(self._writer.root)
            self.report({"INFO"}, f"Dataset written to {self._writer.root}")
        return result

    def invoke(self, context, event):
        self.from_ui = True
        context.window_manager.fileselect_add(self)
        return {"RUNNING_MODAL"}

    def draw(self, context):
        layout = self.layout
        layout.prop(self, "layout")
        col = layout.column(heading="Frames")
        col.prop(self, "use_scene_range")
        sub = col.column(align=True)
        sub.active = not self.use_scene_range
        sub.prop(self, "frame_start")
        sub.prop(self, "frame_end")
        sub.prop(self, "frame_step")
        layout.prop(self, "selected_only")
        layout.prop(self, "classes")
        row = layout.row(heading="Seed")
        row.prop(self, "use_seed", text="")
        sub = row.row()
        sub.active = self.use_seed
        sub.prop(self, "seed", text="")
        if self.layout == "kitti":
            for name in ("intensity", "points_format", "level", "min_points", "val_share",
                         "split_seed"):
                layout.prop(self, name)
        layout.prop(self, "overwrite")
        layout.prop(self, "resume")


def draw_export_menu(self, context):
    self.layout.operator(RLS_OT_export_dataset.bl_idname, text="RLS Dataset (KITTI / OPV2V)")


CLASSES = (RLS_OT_export_dataset,)

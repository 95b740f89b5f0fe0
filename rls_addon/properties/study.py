"""The placement study's properties (``Scene.rls_study``): what the Study panel asks
(the settings of ``rls study``, as text where the command line takes text) and the
last study's table. ``blender.study_job.study_config`` turns them into the core's
``StudyConfig`` in one place."""

import bpy
from bpy.props import (
    BoolProperty,
    CollectionProperty,
    EnumProperty,
    FloatProperty,
    IntProperty,
    PointerProperty,
    StringProperty,
)

from ..blender.sensor import DEFAULT_PRESET
from ..core.choices import BACKENDS, DISK_PLACEMENTS, STUDY_SCORES, YAW_MODES
from ..core.metrics.infra import DEFAULT_CELL_M, DEFAULT_DISKS, DEFAULT_RADIUS_M, DEFAULT_SEED
from ..core.study.placement import DEFAULT_EXHAUSTIVE_LIMIT
from .lidar import preset_accessors, preset_items

MOUNT_ITEMS = [
    ("MARKED", "Marked Mounts", "Every object marked as a mount (custom property rls_mount)"),
    ("SELECTED", "Selected Objects", "The selected objects: a LiDAR would sit on top of each"),
    ("NONE", "Grid Only", "No mounts: candidates on the grid alone"),
]


def _recolor(self, context):
    from ..blender.study_answer import color_markers

    if self.has_result:
        color_markers(context.scene, self.color_by)


def _is_study_image(self, image):
    from ..blender.study_answer import STUDY_PROPERTY

    return bool(image.get(STUDY_PROPERTY))


class RLS_StudyRow(bpy.types.PropertyGroup):
    """One row of the study's table: a candidate (k = 1) or a set of a larger k."""

    k: IntProperty(name="k", description="Sensors in the set")
    sensors: StringProperty(name="Sensors", description="The set's candidates")
    members: StringProperty(name="Members", description="The set's candidate indices")
    points: IntProperty(name="Points", description="Points counted in the region")
    infra_d: FloatProperty(name="InfraD", description="Points per m² in the region")
    infra_nuc: FloatProperty(name="InfraNUC",
                             description="Non-uniformity of the points in the region")
    visibility: FloatProperty(name="Visibility", default=float("nan"),
                              description="Share of vehicle-frames seen by at least 20 "
                                          "points (NaN without traffic frames)")
    ap: FloatProperty(name="AP", default=float("nan"),
                      description="Vehicle AP_R40 at BEV IoU 0.5 (NaN without evaluation "
                                  "frames)")
    pareto: BoolProperty(name="Pareto", description="On the Pareto front of its k")
    best: BoolProperty(name="Best", description="The best set of its k (balanced score)")


_get_device, _set_device = preset_accessors("device_id")


class RLS_StudySettings(bpy.types.PropertyGroup):
    device_id: StringProperty(name="Device Id", default=DEFAULT_PRESET,
                              description="Id of the device preset placed at every candidate")
    device: EnumProperty(name="Device", items=preset_items, get=_get_device, set=_set_device,
                         description="Device placed at every candidate (not the scene's "
                                     "own LiDAR objects)")
    k: StringProperty(name="Sensors (k)", default="1,2",
                      description="Sensors per placement: 2, 1,2,3 or 1:3:1")
    pitches: StringProperty(name="Pitches", default="0",
                            description="Downward pitches in degrees: 0, 0,10,20 or 0:30:10")
    yaws: StringProperty(name="Yaws", default="0",
                         description="Yaws in degrees (same forms as the pitches)")
    yaw_mode: EnumProperty(name="Yaw", items=YAW_MODES.items(), default="face",
                           description="What yaw 0 means")
    roll: FloatProperty(name="Roll", default=0.0, description="Roll in degrees")
    mounts_from: EnumProperty(name="Mounts", items=MOUNT_ITEMS, default="MARKED",
                              description="Where the candidate LiDARs sit")
    use_grid: BoolProperty(name="Grid", default=False,
                           description="Also place candidates on a grid over the region")
    grid_step: FloatProperty(name="Grid Step", default=6.0, min=0.1, unit="LENGTH",
                             description="Spacing of the grid")
    grid_heights: StringProperty(name="Grid Heights", default="6",
                                 description="Heights of the grid's candidates in metres: "
                                             "6 or 5,8")
    grid_margin: FloatProperty(name="Grid Margin", default=0.0, min=0.0, unit="LENGTH",
                               description="Grow the grid beyond the region")
    traffic: StringProperty(name="Traffic Frames", default="",
                            description="Also score placements with the traffic in view over "
                                        "these frames (5, 1-60 or 1-60:5; empty: no)")
    evaluate: StringProperty(name="Evaluate Frames", default="",
                             description="Also judge placements by RLS's roadside detector "
                                         "over these frames (a subset of the traffic frames; "
                                         "empty: no)")
    min_points: IntProperty(name="Min Points", default=5, min=0,
                            description="Evaluation: returns a box needs to count")
    labels: StringProperty(name="Labels", default="road,sidewalk",
                           description="Labels of the points counted in the region")
    disks: IntProperty(name="Disks", default=DEFAULT_DISKS, min=1, soft_max=50000,
                       description="Random disks for InfraNUC")
    radius: FloatProperty(name="Disk Radius", default=DEFAULT_RADIUS_M, min=0.01, unit="LENGTH",
                          description="Radius of the InfraNUC disks")
    disk_seed: IntProperty(name="Disk Seed", default=DEFAULT_SEED, min=0,
                           description="Seed of the random disk placement")
    disk_placement: EnumProperty(name="Disk Placement", items=DISK_PLACEMENTS.items(),
                                 default="inside", description="Where the disks may lie")
    cell: FloatProperty(name="Map Cell", default=DEFAULT_CELL_M, min=0.05, unit="LENGTH",
                        description="Cell size of the density maps")
    seed: IntProperty(name="Scan Seed", default=0, min=0,
                      description="Seed of the scans' noise and dropout")
    noise: BoolProperty(name="Range Noise", default=True,
                        description="Add the device's range noise")
    dropout: BoolProperty(name="Dropout", default=True,
                          description="Drop returns as the device's dropout model says")
    keep_traffic: BoolProperty(name="Keep Traffic", default=False,
                               description="Keep vehicles, pedestrians and cyclists in the "
                                           "scans (the paper removes them)")
    shared_mounts: BoolProperty(name="Shared Mounts", default=False,
                                description="Let a set use several orientations on one mount")
    exhaustive_limit: IntProperty(name="Exhaustive Limit", default=DEFAULT_EXHAUSTIVE_LIMIT,
                                  min=1, description="Evaluate every k-set up to this many, "
                                                     "else greedy + swap")
    backend: EnumProperty(name="Backend", items=BACKENDS.items(), default="auto",
                          description="Ray casting")
    output_dir: StringProperty(name="Report Folder", default="", subtype="DIR_PATH",
                               description="Also write rls study's report files here "
                                           "(empty: only the answer in the scene)")
    overwrite: BoolProperty(name="Overwrite", default=False,
                            description="Replace a report already in the folder")
    # the last study's answer (draw() only shows it)
    color_by: EnumProperty(name="Color By", items=STUDY_SCORES.items(), default="infra_d",
                           update=_recolor,
                           description="Score the candidate markers are coloured by "
                                       "(dark: worst, yellow: best)")
    color_range: StringProperty(name="Colours", default="",
                                description="What the markers' colours span")
    has_result: BoolProperty(default=False, options={"HIDDEN"},
                             description="A study's answer is in the scene")
    summary: StringProperty(name="Summary", default="",
                            description="The last study in one line")
    rows: CollectionProperty(type=RLS_StudyRow, description="The last study's table")
    row_index: IntProperty(name="Row", default=0, description="The table's active row")
    chart: PointerProperty(name="Chart", type=bpy.types.Image, poll=_is_study_image,
                           description="The study chart shown in the panel")

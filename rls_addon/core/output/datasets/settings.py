"""What a dataset export is asked to do (``DatasetSettings``): the layout, folder and
frames, the LiDARs and classes, the scan's overrides and each layout's options.
``rls dataset`` fills one from its flags and *File > Export > RLS Dataset* from its
options; both hand it to the same run (``blender/dataset.py``), so they write the same
files."""

import dataclasses

from ...errors import SceneError
from . import LAYOUTS

INTENSITY_SCALES = {"0-1": 1.0, "0-255": 255.0}
DEFAULT_CLASSES = "vehicle,pedestrian,cyclist"
# sweeps of the scene with every road user hidden stored per still LiDAR (background/):
# what RLS's detector learns its background from (core/scan/background_sweeps.py)
BACKGROUND_SWEEPS = 5


@dataclasses.dataclass(frozen=True)
class DatasetSettings:
    layout: str                      # LAYOUTS: kitti or opv2v
    out: str                         # the dataset folder
    frames: tuple                    # frames to scan, in order
    sensors: tuple = ()              # LiDAR object names (empty: every LiDAR)
    classes: str = DEFAULT_CLASSES   # labels whose objects get boxes (names or ids)
    # overrides of each LiDAR's settings (None: the LiDAR's own)
    seed: int = None
    motion: str = None
    substeps: int = None
    backend: str = None
    ghosting: bool = None
    sweep_start_deg: float = None
    rotation_hz: float = None
    lidar_mode: str = None
    # the kitti layout's options
    intensity: str = "0-1"           # INTENSITY_SCALES
    points_format: str = "npy"       # npy or bin
    level: bool = False
    min_points: int = 1
    val_share: float = 0.2
    split_seed: int = 0
    val_frames: tuple = None         # (first, last) frames for validation
    background_sweeps: int = BACKGROUND_SWEEPS
    overwrite: bool = False
    resume: bool = False

    def __post_init__(self):
        LAYOUTS.check(self.layout)
        if not self.frames:
            raise SceneError("no frames to export (the frame range is empty)")
        if self.substeps is not None and self.substeps < 0:
            raise SceneError(f"--substeps must be >= 0, got {self.substeps}")
        if self.background_sweeps < 0:
            raise SceneError("--background-sweeps must be 0 or more, got "
                             f"{self.background_sweeps}")
        if self.intensity not in INTENSITY_SCALES:
            raise SceneError(f"intensity scale must be one of {', '.join(INTENSITY_SCALES)}, "
                             f"got {self.intensity!r}")
        object.__setattr__(self, "frames", tuple(int(f) for f in self.frames))
        object.__setattr__(self, "sensors", tuple(self.sensors))

    def scan_changes(self, class_names):
        """The changes to every LiDAR's settings (``LidarSettings.override``): sensor
        frame, ground truth of ``class_names``, and the overrides given."""
        return {"seed": self.seed, "motion": self.motion, "substeps": self.substeps,
                "backend": self.backend, "frame_space": "sensor", "ground_truth": True,
                "object_classes": tuple(class_names), "ghosting": self.ghosting,
                "sweep_start_deg": self.sweep_start_deg, "rotation_hz": self.rotation_hz,
                "lidar_mode": self.lidar_mode}

    def writer(self, scene_name, sensors, carriers, background=False):
        """The layout's writer for LiDARs ``sensors`` (names) of scene ``scene_name``;
        ``carriers`` {sensor: the vehicle it rides on, or None} makes OPV2V's agents
        and the vehicles KITTI's labels leave out;
        ``background``: KITTI's frames written behind the scan (``io.behind``)."""
        from .common import Split
        from .kitti import KittiWriter
        from .opv2v import Opv2vWriter, agents_for

        riding = {k: v for k, v in carriers.items() if v}  # the LiDARs on a vehicle
        if self.layout == "kitti":
            return KittiWriter(self.out, scene_name,
                               intensity_scale=INTENSITY_SCALES[self.intensity],
                               points_format=self.points_format, level=self.level,
                               min_points=self.min_points,
                               split=Split(self.val_share, self.split_seed, self.val_frames),
                               overwrite=self.overwrite, resume=self.resume,
                               background=background, carriers=riding)
        return Opv2vWriter(self.out, scene_name, agents_for(list(sensors), carriers), riding,
                           overwrite=self.overwrite, resume=self.resume)

"""What a placement study is asked to do (``StudyConfig``): the device, the k, the
candidate mounts or grid and their orientations, the region's disks, the scan's effects,
and the traffic frames for visibility. The command line and the Study panel fill it.

As in the paper, traffic is removed before the metrics are taken: the study scene
leaves objects labelled ``TRAFFIC_LABELS`` out of the geometry (the scene itself is not
changed)."""

import dataclasses

from ..errors import SceneError
from ..metrics.infra import DEFAULT_CELL_M, DEFAULT_DISKS, DEFAULT_RADIUS_M, DEFAULT_SEED
from ..metrics.visibility import THRESHOLDS
from .placement import DEFAULT_EXHAUSTIVE_LIMIT


TRAFFIC_LABELS = ("vehicle", "pedestrian", "cyclist")


@dataclasses.dataclass
class StudyConfig:
    device: str = "generic_uniform32"
    k: tuple = (1,)
    lob: str = None                 # region object name (default: the one marked object)
    mounts: tuple = ()              # mount object names (default: every marked mount)
    grid_step: float = None         # grid of positions instead of (or besides) mounts
    grid_heights: tuple = (6.0,)
    grid_margin: float = 0.0
    pitches: tuple = (0.0,)         # degrees, positive tilts the sensor's +X down
    yaws: tuple = (0.0,)            # degrees
    yaw_mode: str = "face"          # "face": yaw relative to facing the region centre
    roll: float = 0.0
    labels: str = "road,sidewalk"
    disks: int = DEFAULT_DISKS
    radius: float = DEFAULT_RADIUS_M
    disk_seed: int = DEFAULT_SEED
    disk_placement: str = "inside"
    cell: float = DEFAULT_CELL_M
    scan_seed: int = 0
    noise: bool = True
    dropout: bool = True
    ghosting: bool = True
    keep_traffic: bool = False
    backend: str = "auto"
    frame: int = None
    one_per_mount: bool = True
    exhaustive_limit: int = DEFAULT_EXHAUSTIVE_LIMIT
    # Placements scored with the traffic in view (``visibility``): these frames of the
    # scene's animated traffic, and the labels whose objects are scored
    traffic_frames: tuple = ()
    visibility_labels: tuple = ("vehicle",)
    visibility_thresholds: tuple = THRESHOLDS
    # Placements scored by detection (``evaluation``): RLS's roadside detector on these
    # frames of the traffic (they are traffic frames too: the default traffic frames
    # when none are given), and the returns the study's candidates together must put
    # on a box for it to count
    evaluate_frames: tuple = ()
    evaluate_min_points: int = 5
    # The device's rotation rate (a mode or a unit's measured rate) and lidar mode
    # (``device.modes.with_modes``); None: the preset's
    rotation_hz: float = None
    lidar_mode: str = None

    def __post_init__(self):
        if self.evaluate_frames and not self.traffic_frames:
            self.traffic_frames = tuple(self.evaluate_frames)
        extra = sorted(set(self.evaluate_frames) - set(self.traffic_frames))
        if extra:
            raise SceneError(f"frames {extra[:5]} to evaluate are not among the traffic "
                             "frames: evaluate a subset of --traffic, or leave --traffic out")
        if self.evaluate_frames and int(self.evaluate_min_points) < 0:
            raise SceneError("the points a box needs to count must be 0 or more")


# The settings a user types as text (a list of numbers or frames, a list of labels),
# and what the command line calls each (the panel names them by its own labels)
TEXT_FIELDS = {"k": "--k", "grid_heights": "--heights", "pitches": "--pitch",
               "yaws": "--yaw", "traffic_frames": "--traffic",
               "evaluate_frames": "--evaluate", "visibility_labels": "--visibility-labels"}


def study_config(names=None, **fields):
    """The ``StudyConfig`` of settings as a user gives them, the one way the command
    line (``rls study``) and the Study panel make it: the fields of ``TEXT_FIELDS``
    may be text (``k="1,2"``, ``pitches="0:30:15"``, ``traffic_frames="1-60:5"``, empty
    or None for no frames, ``visibility_labels="vehicle"``); the rest are
    ``StudyConfig``'s own. ``names`` maps a field to what the user knows it as, for
    the errors (default: the command line's flags)."""
    from ..labels import label_ids, label_name
    from ..ranges import parse_frames, parse_values

    names = dict(TEXT_FIELDS, **(names or {}))
    out = dict(fields)
    if "k" in fields:
        values = parse_values(fields["k"], names["k"])
        if any(v < 1 or v != int(v) for v in values):
            raise SceneError(f"{names['k']}: sensor counts must be positive integers, "
                             f"got {fields['k']}")
        out["k"] = tuple(sorted({int(v) for v in values}))
    for field in ("grid_heights", "pitches", "yaws"):
        if field in fields:
            out[field] = tuple(parse_values(fields[field], names[field]))
    for field in ("traffic_frames", "evaluate_frames"):
        if field in fields:
            text = fields[field]
            if isinstance(text, str):
                text = text.strip()
                out[field] = tuple(parse_frames(text, 0, names[field])) if text else ()
            else:
                out[field] = tuple(int(f) for f in text or ())
    if "visibility_labels" in fields and isinstance(fields["visibility_labels"], str):
        out["visibility_labels"] = tuple(label_name(i)
                                         for i in label_ids(fields["visibility_labels"]))
    if "mounts" in fields:
        out["mounts"] = tuple(fields["mounts"])
    return StudyConfig(**out)

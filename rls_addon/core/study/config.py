"""What a placement study is asked to do (``StudyConfig``): the device, the k, the
candidate mounts or grid and their orientations, the region's disks, the scan's effects,
and the traffic frames for visibility. The command line and the Study panel fill it.

As in the paper, traffic is removed before the metrics are taken: the study scene
leaves objects labelled ``TRAFFIC_LABELS`` out of the geometry (the scene itself is not
changed)."""

import dataclasses
import math

from ..choices import BACKGROUNDS
from ..errors import RegionError, SceneError
from ..labels import ROAD_USERS
from ..scan.background_sweeps import BACKGROUND_SWEEPS
from ..metrics.infra import DEFAULT_CELL_M, DEFAULT_DISKS, DEFAULT_RADIUS_M, DEFAULT_SEED
from ..metrics.visibility import THRESHOLDS
from .placement import DEFAULT_EXHAUSTIVE_LIMIT


TRAFFIC_LABELS = ROAD_USERS


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
    # The detector (``evaluate.detector.protocol``); None: RLS's roadside detector with
    # the device's range noise and the scene's own types of road users
    detector: object = None
    # Its background (``choices.BACKGROUNDS``): 'empty', each candidate's sweeps of the
    # scene with every road user hidden (``background_sweeps`` of them, as a deployed
    # unit has), or 'frames', learned from the evaluation frames themselves
    evaluate_background: str = "empty"
    background_sweeps: int = BACKGROUND_SWEEPS
    # Sets of each k > 1 scored by detection beyond the reported ones (drawn from those
    # the search looked at), for the correlation within k
    evaluate_sets: int = 20
    # The device's rotation rate (a mode or a unit's measured rate) and lidar mode
    # (``device.modes.with_modes``); None: the preset's
    rotation_hz: float = None
    lidar_mode: str = None

    def __post_init__(self):
        for name in ("roll", "grid_margin"):
            if not math.isfinite(float(getattr(self, name))):
                raise SceneError(f"the {name.replace('_', ' ')} must be a finite number, got "
                                 f"{getattr(self, name)}")
        if self.evaluate_frames and not self.traffic_frames:
            self.traffic_frames = tuple(self.evaluate_frames)
        extra = sorted(set(self.evaluate_frames) - set(self.traffic_frames))
        if extra:
            raise SceneError(f"frames {extra[:5]} to evaluate are not among the traffic "
                             "frames: evaluate a subset of --traffic, or leave --traffic out")
        if self.evaluate_frames and int(self.evaluate_min_points) < 0:
            raise SceneError("the points a box needs to count must be 0 or more")
        BACKGROUNDS.check(self.evaluate_background)
        if int(self.evaluate_sets) < 0:
            raise SceneError(f"the sets to score beyond the reported ones must be 0 or "
                             f"more, got {self.evaluate_sets}")
        if self.evaluate_background == "empty" and int(self.background_sweeps) < 1:
            raise SceneError(f"the empty scene's background needs at least one sweep, got "
                             f"{self.background_sweeps}")


def parse_values(text, what="values"):
    """Numbers as a user types them (``what`` names the setting in the error): '10' ->
    [10.0]; '0,10,20' -> list; '0:30:10' -> 0,10,20,30 (inclusive range)."""
    if isinstance(text, (int, float)):
        return [float(text)]
    text = str(text).strip()
    bad = RegionError(f"{what}: expected V, V1,V2,... or START:STOP:STEP, got {text!r}")
    try:
        if ":" in text:
            parts = [float(t) for t in text.split(":")]
            if len(parts) != 3 or not all(math.isfinite(v) for v in parts) or parts[2] <= 0:
                raise bad
            a, b, step = parts
            count = int(math.floor((b - a) / step + 1e-9)) + 1
            if count < 1:
                raise bad
            return [round(a + i * step, 9) for i in range(count)]
        vals = [float(t) for t in text.split(",") if t.strip()]
    except ValueError:
        raise bad from None
    if not vals:
        raise RegionError(f"{what}: no values in {text!r}")
    if not all(math.isfinite(v) for v in vals):
        # nan and inf parse as floats: a candidate's pose of them had ended in numpy's
        # "SVD did not converge", a k of them in a ValueError
        raise RegionError(f"{what}: every value must be a finite number, got {text!r}")
    return vals


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
    from ..scan.frames import parse_frames

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

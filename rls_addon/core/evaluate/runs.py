"""What ``rls detect`` and ``rls evaluate`` run, as settings objects and one call each,
so the command line and the *Detect and Evaluate* panel run the same:

* ``DetectSettings`` -> ``run_detection``: RLS's roadside detector over kitti datasets
  (``detect_dataset``), its boxes written as detection files;
* ``EvaluateSettings`` -> ``evaluate``: ground truth and detections read from their
  files and scored in the region (``scoring.score``).
"""

import dataclasses
import json
import math
from pathlib import Path

from ..errors import InputError, OutputError

DEFAULT_CLASSES = ("vehicle", "pedestrian", "cyclist")
DEFAULT_IOU = (0.3, 0.5, 0.7)
# kitti label ids of the classes the detector finds (core/labels.py)
DETECTED = (("vehicle", 11), ("pedestrian", 12), ("cyclist", 18))
MAX_NOISE_SIGMA_M = 1.0  # the presets' range noise is 0-3 cm; a metre is no LiDAR's


@dataclasses.dataclass(frozen=True)
class DetectSettings:
    datasets: tuple                  # kitti sensor roots, fused early
    out: str                         # the folder of detection files
    background_frames: tuple = None  # with background "frames": the frames (None: all)
    noise_sigma: float = None        # the device's range noise (None: its preset's)
    overwrite: bool = False
    background: str = "empty"        # choices.BACKGROUNDS: the dataset's sweeps of the
                                     # scene without road users, or the frames themselves

    def __post_init__(self):
        check_noise_sigma(self.noise_sigma)


def check_noise_sigma(value):
    """``--noise-sigma``: None (the preset's) or a range noise in [0, 1] m. NaN and a
    negative value were taken and changed nothing (the margin is the larger of a
    minimum and 5 sigma)."""
    if value is None:
        return
    if not math.isfinite(value) or not 0.0 <= value <= MAX_NOISE_SIGMA_M:
        raise InputError(f"--noise-sigma must be the device's range noise in metres, from 0 "
                         f"to {MAX_NOISE_SIGMA_M:g} (the presets': 0 to 0.03), got {value!r}")


def check_detection_folder(out, overwrite):
    """Refuse, before any work, an --out that is a file, or a folder holding detection
    files without ``overwrite``."""
    out = Path(out)
    if out.exists() and not out.is_dir():
        raise OutputError(f"--out {out} is a file, not a folder")
    if out.is_dir() and any(out.glob("*.txt")) and not overwrite:
        raise OutputError(f"{out} already holds detection files: use --overwrite to replace "
                          "them, or choose another folder")


def run_detection(settings, progress=None):
    """Detect every frame the datasets share and write the boxes with ``detector.json``
    (the detector and the background it learned); returns a dict: boxes, frames, timing
    (``detect_datasets``'), paths, counts per class and about (detector.json's)."""
    from .detect_dataset import detect_datasets, write_dataset_detections
    from .kitti_meta import KittiMeta, one_scene

    check_detection_folder(settings.out, settings.overwrite)
    roots = list(settings.datasets)
    one_scene([(str(d), KittiMeta.open(d)) for d in roots])  # fused: one scene
    boxes, done, timing = detect_datasets(roots, settings.background,
                                          settings.background_frames, settings.noise_sigma,
                                          progress)
    about = {"detector": timing["detector"], "background": timing["background"],
             "size_priors": timing["types"], "sensors": timing["sensors"],
             "datasets": [str(d) for d in roots], "frames": done}
    paths = write_dataset_detections(Path(settings.out), boxes, roots, done, overwrite=True,
                                     about=about)
    counts = {name: int((boxes.label == lid).sum()) for name, lid in DETECTED}
    return {"boxes": boxes, "frames": done, "timing": timing, "paths": paths,
            "counts": counts, "about": about}


@dataclasses.dataclass(frozen=True)
class EvaluateSettings:
    truth: tuple                     # kitti datasets or sidecar folders (several: merged)
    detections: str                 # NNNNNN.txt folder, result.pkl or OpenCOOD's npy folder
    format: str = "auto"             # auto, kitti, openpcdet, opencood
    dataset: str = None              # whose poses place the detections
    scenario: str = None             # opencood: the scenario
    region: tuple = None             # ((x, y), ...) world metres (None: everywhere)
    region_name: str = None          # how the region is described
    min_points: int = 5
    classes: tuple = DEFAULT_CLASSES
    iou_thresholds: tuple = DEFAULT_IOU
    distance_bins: tuple = None


def kitti_roots(path):
    """The kitti sensor roots at ``path`` (itself, or every sensor folder under it), or
    [] when it is not a kitti dataset."""
    p = Path(path)
    if (p / "meta").is_dir():
        return [p]
    if p.is_dir():
        return sorted(d for d in p.iterdir() if (d / "meta").is_dir())
    return []


def _sidecar_sensors(path):
    """The sensors whose sidecars with ground truth are at ``path``."""
    p = Path(path)
    files = [p] if p.is_file() else sorted(p.rglob("*.json")) if p.is_dir() else []
    names = []
    for f in files:
        try:
            info = json.loads(f.read_text(encoding="utf-8"))
        except (OSError, ValueError, UnicodeDecodeError):
            continue  # the reader names what it cannot read
        if isinstance(info, dict) and "objects" in info:
            name = str(info.get("sensor", ""))
            if name not in names:
                names.append(name)
    return names or [None]


def read_truths(paths):
    """([GroundTruth] one per sensor, [kitti sensor roots]) of the --truth paths."""
    from .ground_truth_files import ground_truth_from_kitti, ground_truth_from_sidecars

    truths, roots = [], []
    for path in paths:
        if not Path(path).exists():
            raise InputError(f"--truth {path}: no such dataset or sidecar folder")
        found = kitti_roots(path)
        if found:
            truths += [ground_truth_from_kitti(r) for r in found]
            roots += found
        else:
            truths += [ground_truth_from_sidecars(path, s) for s in _sidecar_sensors(path)]
    return truths, roots


def _dataset(settings, fmt, roots, n_truth):
    if settings.dataset:
        return settings.dataset
    if fmt == "opencood":
        raise InputError("opencood predictions need --dataset: the OPV2V test root they were "
                         "made on (the folder of scenario folders OpenCOOD read)")
    if n_truth == 1 and len(roots) == 1:
        return roots[0]
    why = "several sensors' ground truth is given" if n_truth > 1 else \
        "--truth is scan sidecars, not an RLS kitti dataset"
    raise InputError(f"{fmt} detections are in the frame of the dataset the detector ran on, "
                     f"and {why}: give --dataset, the RLS kitti sensor folder whose points "
                     "the detector read")


def _one_scene(roots, dataset, fmt):
    """The kitti datasets given (ground truth, and the one the detector ran on) must
    name one scene (their dataset.json)."""
    from .kitti_meta import KittiMeta, one_scene

    given = [(f"--truth {r}", KittiMeta.open(r)) for r in roots]
    if fmt != "opencood" and Path(dataset) not in roots:
        given.append((f"--dataset {dataset}", KittiMeta.open(dataset)))
    one_scene(given)


def evaluate(settings):
    """The scoring of ``settings.detections`` against the ground truth (``score``'s
    result with its notices and inputs)."""
    from .detect_dataset import read_about
    from .readers import detect_format, read_detection_files
    from .scoring import score

    truths, roots = read_truths(settings.truth)
    fmt = detect_format(settings.detections) if settings.format == "auto" else settings.format
    dataset = _dataset(settings, fmt, roots, len(truths))
    _one_scene(roots, dataset, fmt)
    files = read_detection_files(settings.detections, fmt, dataset, settings.scenario)
    region = None if settings.region is None else [list(map(float, v)) for v in settings.region]
    result = score(truths, files, region=region, min_points=settings.min_points,
                   classes=list(settings.classes), iou_thresholds=list(settings.iou_thresholds),
                   distance_bins=None if settings.distance_bins is None
                   else list(settings.distance_bins))
    result["notices"] = files.notices + result["notices"]
    result["inputs"] = {"truth": [str(p) for p in settings.truth],
                        "detections": str(settings.detections), "format": fmt,
                        "dataset": str(dataset), "region": settings.region_name,
                        "detector": read_about(settings.detections)}
    return result


def result_json(result):
    """The bytes of ``evaluate``'s result as ``rls evaluate --out`` writes them."""
    return (json.dumps(result, indent=1, allow_nan=False) + "\n").encode("utf-8")

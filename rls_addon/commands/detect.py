"""``rls detect``: RLS's built-in roadside detector over datasets of still LiDARs.

    rls detect out/ds/L_TL_SW --out out/det
    rls detect out/ds/L_TL_SW out/ds/L_TL_NE --out out/det_fused   (early fusion)

Each DATASET is a sensor root that ``rls dataset --layout kitti`` wrote. The detector
learns each sensor's background from the frames (``--background-frames`` to choose
them, e.g. frames without traffic), then finds the objects of every frame the datasets
share: foreground in the sensor's own range image, clustered over every sensor
(DBSCAN), an oriented box and a class by size per cluster. It reads only the points'
x, y, z, never RLS's labels. The detections are written as one ``NNNNNN.txt`` per frame
in the first dataset's label frame (``x y z dx dy dz heading Class score``), the format
``rls evaluate --detections`` reads. It is not a learned detector: see docs/evaluate.md.
"""

import math
import sys
from pathlib import Path

from ..core.errors import InputError, OutputError

MAX_NOISE_SIGMA_M = 1.0  # the presets' range noise is 0-3 cm; a metre is no LiDAR's


def add_parser(sub):
    p = sub.add_parser("detect", help="RLS's roadside detector over kitti-layout datasets",
                       description=__doc__.split("\n\n", 1)[1],
                       formatter_class=__import__("argparse").RawDescriptionHelpFormatter)
    p.add_argument("datasets", nargs="+", metavar="DATASET",
                   help="sensor roots written by 'rls dataset --layout kitti'")
    p.add_argument("--out", required=True, help="folder for the detection files")
    p.add_argument("--background-frames", metavar="A-B[:STEP]",
                   help="frames to learn the background from (default: every frame)")
    p.add_argument("--noise-sigma", type=float, metavar="M",
                   help="the device's range noise in m, 0 to 1 (default: its preset's)")
    p.add_argument("--overwrite", action="store_true", help="replace existing detection files")
    p.set_defaults(func=run)


def check_noise_sigma(value):
    """``--noise-sigma``: None (the preset's) or a range noise in [0, 1] m. NaN and a
    negative value were taken and changed nothing (the margin is the larger of a
    minimum and 5 sigma)."""
    if value is None:
        return
    if not math.isfinite(value) or not 0.0 <= value <= MAX_NOISE_SIGMA_M:
        raise InputError(f"--noise-sigma must be the device's range noise in metres, from 0 "
                         f"to {MAX_NOISE_SIGMA_M:g} (the presets': 0 to 0.03), got {value!r}")


def run(args):
    from ..core.evaluate.detect_dataset import detect_datasets, write_dataset_detections
    from .scan import parse_frames

    check_noise_sigma(args.noise_sigma)
    out = Path(args.out)
    if out.exists() and not out.is_dir():
        raise OutputError(f"--out {out} is a file, not a folder")
    if out.is_dir() and any(out.glob("*.txt")) and not args.overwrite:
        raise OutputError(f"{out} already holds detection files: use --overwrite to replace "
                          "them, or choose another folder")
    frames = parse_frames(args.background_frames, None) if args.background_frames else None
    from ..core.evaluate.kitti_meta import KittiMeta, one_scene

    one_scene([(str(d), KittiMeta.open(d)) for d in args.datasets])  # fused: one scene

    def progress(i, n, frame):
        print(f"[{i}/{n}] frame {frame}", file=sys.stderr, flush=True)

    boxes, done, timing = detect_datasets(args.datasets, frames, args.noise_sigma, progress)
    paths = write_dataset_detections(out, boxes, args.datasets, done, overwrite=True)
    per_frame = sorted(timing["detect_s"])[len(timing["detect_s"]) // 2] * 1000
    counts = {name: int((boxes.label == lid).sum())
              for name, lid in (("vehicle", 11), ("pedestrian", 12), ("cyclist", 18))}
    print(f"{len(boxes)} detections in {len(done)} frames of {', '.join(timing['sensors'])} "
          f"({', '.join(f'{v} {k}' for k, v in counts.items())}); background learned in "
          f"{timing['learn_s']:.1f} s, {per_frame:.1f} ms a frame (median)\n"
          f"Detections: {out} ({len(paths)} files)")
    return 0

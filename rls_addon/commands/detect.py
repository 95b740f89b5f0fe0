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

import sys


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
                   help="the device's range noise in m (default: its preset's)")
    p.add_argument("--overwrite", action="store_true", help="replace existing detection files")
    p.set_defaults(func=run)


def run(args):
    from ..core.evaluate.runs import DetectSettings, check_detection_folder, run_detection
    from ..core.scan.frames import parse_frames

    check_detection_folder(args.out, args.overwrite)
    frames = (parse_frames(args.background_frames, None, "--background-frames")
              if args.background_frames else None)

    def progress(i, n, frame):
        print(f"[{i}/{n}] frame {frame}", file=sys.stderr, flush=True)

    found = run_detection(DetectSettings(tuple(args.datasets), args.out, frames,
                                         args.noise_sigma, args.overwrite), progress)
    timing, counts = found["timing"], found["counts"]
    per_frame = sorted(timing["detect_s"])[len(timing["detect_s"]) // 2] * 1000
    print(f"{len(found['boxes'])} detections in {len(found['frames'])} frames of "
          f"{', '.join(timing['sensors'])} ({', '.join(f'{v} {k}' for k, v in counts.items())}); "
          f"background learned in {timing['learn_s']:.1f} s, {per_frame:.1f} ms a frame "
          f"(median)\nDetections: {args.out} ({len(found['paths'])} files)")
    return 0

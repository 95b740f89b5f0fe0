"""``rls detect``: RLS's built-in roadside detector over datasets of still LiDARs.

    rls detect out/ds/L_TL_SW --out out/det
    rls detect out/ds/L_TL_SW out/ds/L_TL_NE --out out/det_fused   (early fusion)

Each DATASET is a sensor root that ``rls dataset --layout kitti`` wrote. The detector
learns each sensor's background from the sweeps of the scene with every road user hidden
that the dataset stores (background/: what a deployed unit has; --background empty, the
default), or from the frames themselves (--background frames, --background-frames to
choose them), then finds the objects of every frame the datasets share: foreground in
the sensor's own range image, clustered over every sensor (DBSCAN), an oriented box and a
class by size per cluster. It reads only the points' x, y, z, never RLS's labels. The
detections are written as one ``NNNNNN.txt`` per frame in the first dataset's label
frame (``x y z dx dy dz heading Class score``), the format ``rls evaluate --detections``
reads, with detector.json (the detector and its background) beside them. It is not a
learned detector: see docs/evaluate.md.
"""


from ..core.choices import BACKGROUNDS
from .stderr import say


def add_parser(sub):
    p = sub.add_parser("detect", help="RLS's roadside detector over kitti-layout datasets",
                       description=__doc__.split("\n\n", 1)[1],
                       formatter_class=__import__("argparse").RawDescriptionHelpFormatter)
    p.add_argument("datasets", nargs="+", metavar="DATASET",
                   help="sensor roots written by 'rls dataset --layout kitti'")
    p.add_argument("--out", required=True, help="folder for the detection files")
    p.add_argument("--background", choices=BACKGROUNDS.ids, default=None,
                   help="empty (default): learn each sensor's background from the dataset's "
                        "sweeps of the scene without road users; frames: from the frames, "
                        "traffic and all (standing vehicles become background)")
    p.add_argument("--background-frames", metavar="A-B[:STEP]",
                   help="with --background frames: the frames to learn from (default: "
                        "every frame; given alone, it implies --background frames)")
    p.add_argument("--noise-sigma", type=float, metavar="M",
                   help="the device's range noise in m, 0 to 1 (default: its preset's)")
    p.add_argument("--overwrite", action="store_true", help="replace existing detection files")
    p.set_defaults(func=run)


def run(args):
    from ..core.evaluate.runs import DetectSettings, check_detection_folder, run_detection
    from ..core.scan.frames import parse_frames

    check_detection_folder(args.out, args.overwrite)
    frames = (parse_frames(args.background_frames, None, "--background-frames")
              if args.background_frames else None)

    def progress(i, n, frame):
        say(f"[{i}/{n}] frame {frame}")

    background = args.background or ("frames" if frames is not None else "empty")
    found = run_detection(DetectSettings(tuple(args.datasets), args.out, frames,
                                         args.noise_sigma, args.overwrite, background), progress)
    timing, counts = found["timing"], found["counts"]
    per_frame = sorted(timing["detect_s"])[len(timing["detect_s"]) // 2] * 1000
    print(f"{len(found['boxes'])} detections in {len(found['frames'])} frames of "
          f"{', '.join(timing['sensors'])} ({', '.join(f'{v} {k}' for k, v in counts.items())}); "
          f"background learned in {timing['learn_s']:.1f} s, {per_frame:.1f} ms a frame "
          f"(median)\nBackground: {_background_text(timing['background'])}\n"
          f"Detections: {args.out} ({len(found['paths'])} files)")
    return 0


def _background_text(b):
    if b["kind"] == "empty":
        sweeps = sorted(set(b["sweeps"].values()))
        return (f"{BACKGROUNDS.label('empty').lower()}: {'/'.join(map(str, sweeps))} sweep(s) "
                "per sensor of the scene with every road user hidden (the dataset's "
                "background/)")
    return (f"{BACKGROUNDS.label('frames').lower()}: learned from {len(b['frames'])} "
            "frame(s), traffic and all")

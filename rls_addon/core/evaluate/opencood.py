"""OpenCOOD's saved predictions (``opencood/tools/inference.py --save_npy``) on an
OPV2V dataset RLS wrote (``datasets/opv2v.py``).

Checked at the source (DerrickXuNu/OpenCOOD, main of 2024-08-16):

- ``opencood/tools/inference.py`` runs the test set with batch size 1, unshuffled,
  and for sample ``i`` calls ``inference_utils.save_prediction_gt(pred_box_tensor,
  gt_box_tensor, batch_data['ego']['origin_lidar'][0], i, <model_dir>/npy)``;
- ``opencood/tools/inference_utils.py`` ``save_prediction_gt`` writes
  ``%04d_pred.npy`` (the predictions), ``%04d_gt.npy_test`` (its ground truth) and
  ``%04d_pcd.npy`` (the ego's points): the number is the sample index ``i``, not a
  frame. Predictions are (N, 8, 3) corners (``post_process`` of
  ``opencood/data_utils/post_processor/voxel_postprocessor.py``:
  ``boxes_to_corners_3d`` then ``project_box3d`` into the ego), float32 from torch.
  **No scores are saved** (``pred_score`` is computed but not written): every box
  read here has score 1, so average precision over them is a single point. A sample
  without predictions makes ``save_prediction_gt`` fail on ``None``, so a folder ends
  at the first such sample.
- Frame: the ego's LiDAR frame at the current timestamp (``basedataset.py``
  ``reform_param``: ``x1_to_x2(cav lidar_pose, ego lidar_pose)``; the ego's own
  ``transformation_matrix`` is the identity), in CARLA's left-handed axes: OpenCOOD
  uses the .pcd points and the YAML poses as they are, without mirroring.
- Sample order (``opencood/data_utils/datasets/basedataset.py``): the scenario folders
  of the test root sorted by name; in each, the agent folders sorted by name (as
  strings), the first moved to the end when its id is negative (a road-side unit);
  the first agent then is the ego, and its ``*.yaml`` files (names without
  'additional') sorted give the timestamps; the sample index runs over scenarios, then
  timestamps.

RLS's OPV2V layout (``datasets/opv2v.py``, ``carla.py``): points in the LiDAR's own
frame with y mirrored (CARLA's axes), ``lidar_pose`` ``[x, y, z, roll, yaw, pitch]``
(metres, degrees) of the LiDAR at the sweep start in CARLA's world, such that
``carla.blender_matrix(lidar_pose)`` is RLS's sensor pose. So a corner ``p`` of the
ego frame is at ``blender_matrix(ego lidar_pose) @ (p with y mirrored)`` in RLS's
world; the box is fitted to its world corners (``corners.corners_to_boxes``). A LiDAR
that moved during its sweep has its points in its frame at the sweep start, the frame
of ``lidar_pose`` (``datasets.opv2v.points_at_sweep_start``; its settings record
``points_frame``); datasets written before that had them each in its frame at their
own time: their boxes are off by its travel until it scanned them, and a notice says
so. The
frame is the timestamp's number (RLS names the files by frame). OPV2V knows one class:
every box is a vehicle."""

import re
from pathlib import Path

import numpy as np

from ..output.datasets.carla import blender_matrix
from ..errors import InputError
from ..labels import NAME_TO_ID
from .corners import corners_to_boxes
from .detections import Boxes
from .frame_ids import frame_number

PRED = re.compile(r"^(.+)_pred\.npy$")
VEHICLE = NAME_TO_ID["vehicle"]


def _yaml():
    try:
        import yaml
    except ImportError:
        raise InputError("reading OPV2V's YAML files needs PyYAML, which is not installed: "
                         "pip install pyyaml") from None
    return yaml


def opv2v_samples(root):
    """[(scenario folder, ego agent folder, timestamp)] of an OPV2V test root in
    OpenCOOD's sample order (see the module docstring)."""
    root = Path(root)
    if not root.is_dir():
        raise InputError(f"{root}: no such OPV2V dataset folder")
    scenarios = sorted((d for d in root.iterdir() if d.is_dir()), key=lambda d: d.name)
    if scenarios and all(_agent_folder(d) for d in scenarios):
        raise InputError(f"{root}: this is one scenario's folder (its sub-folders are agents); "
                         "give the folder OpenCOOD read as its test set (validate_dir), "
                         "the one holding the scenario folders")
    out = []
    for sc in scenarios:
        cavs = sorted((d.name for d in sc.iterdir() if d.is_dir()))
        if not cavs:
            raise InputError(f"{sc}: a scenario without agent folders (OpenCOOD needs one)")
        try:
            first = int(cavs[0])
        except ValueError:
            raise InputError(f"{sc / cavs[0]}: agent folder name {cavs[0]!r} is not an agent "
                             "id (OPV2V names agent folders by their integer id)") from None
        if first < 0:
            cavs = cavs[1:] + [cavs[0]]
        ego = sc / cavs[0]
        stamps = sorted(p.name for p in ego.iterdir()
                        if p.name.endswith(".yaml") and "additional" not in p.name)
        out += [(sc, ego, s.replace(".yaml", "")) for s in stamps]
    if not out:
        raise InputError(f"{root}: no OPV2V scenario with frames (scenario/agent/NNNNNN.yaml)")
    return out


def _agent_folder(d):
    try:
        int(d.name)
    except ValueError:
        return False
    return any(p.suffix == ".yaml" for p in d.iterdir())


def ego_pose(ego, stamp):
    """(RLS's 4x4 world pose of the ego LiDAR at ``stamp``, whether RLS says it moved
    during that sweep with its points each at their own time: not in the frame of its
    ``lidar_pose``) from its YAML."""
    path = ego / f"{stamp}.yaml"
    try:
        body = _yaml().safe_load(path.read_text(encoding="utf-8"))
        pose = [float(v) for v in body["lidar_pose"]]
    except (OSError, ValueError, TypeError, KeyError) as exc:
        raise InputError(f"{path}: no readable lidar_pose [x, y, z, roll, yaw, pitch] "
                         f"({type(exc).__name__}: {exc})") from None
    except Exception as exc:  # noqa: BLE001 - yaml's own errors
        raise InputError(f"cannot read {path}: {exc}") from None
    if len(pose) != 6 or not np.isfinite(pose).all():
        raise InputError(f"{path}: lidar_pose must be 6 finite numbers, got {pose}")
    rls = body.get("rls") if isinstance(body.get("rls"), dict) else {}
    settings = rls.get("settings") if isinstance(rls.get("settings"), dict) else {}
    skewed = bool(rls.get("sensor_moves")) and settings.get("points_frame") != "lidar_pose"
    return blender_matrix(pose), skewed


def prediction_files(folder):
    """{sample index: path} of a folder's ``NNNN_pred.npy`` files."""
    folder = Path(folder)
    if not folder.is_dir():
        raise InputError(f"{folder}: no such folder of OpenCOOD predictions")
    out = {}
    for p in sorted(folder.iterdir()):
        m = PRED.match(p.name)
        if m:
            out[frame_number(m.group(1), str(p))] = p
    if not out:
        raise InputError(f"{folder}: no OpenCOOD predictions (NNNN_pred.npy, written by "
                         "opencood/tools/inference.py --save_npy into <model_dir>/npy)")
    return out


def load_corners(path):
    """(N, 8, 3) float64 corners of a ``*_pred.npy`` (no pickles: arrays only)."""
    try:
        c = np.load(path, allow_pickle=False)
    except (OSError, ValueError, EOFError) as exc:
        raise InputError(f"cannot read {path} as a numpy array: {exc}") from None
    if c.size == 0:
        return np.zeros((0, 8, 3))
    if c.ndim != 3 or c.shape[1:] != (8, 3):
        raise InputError(f"{path}: shape {c.shape}; OpenCOOD's predictions are (N, 8, 3) "
                         "box corners")
    return c.astype(np.float64)


def corners_to_world(corners, pose):
    """(N, 8, 3) corners of the ego frame (CARLA axes) in RLS's world."""
    c = np.asarray(corners, np.float64).copy()
    c[..., 1] *= -1.0
    return c @ pose[:3, :3].T + pose[:3, 3]


def read_opencood_npy(folder, dataset, scenario=None, notices=None):
    """(Boxes in the world, frames read) of OpenCOOD's ``npy`` folder, made on the OPV2V
    test root ``dataset`` (the folder of scenario folders OpenCOOD read).
    ``scenario``: the scenario to read when the predictions span several (Boxes carry
    frame numbers only). ``notices``: a list that gets what the user should be told."""
    files = prediction_files(folder)
    samples = opv2v_samples(dataset)
    if max(files) >= len(samples):
        raise InputError(f"{files[max(files)]}: sample {max(files)} but {dataset} has "
                         f"{len(samples)} samples in OpenCOOD's order; were the predictions "
                         "made on another dataset?")
    picked = {i: samples[i] for i in files}
    names = sorted({sc.name for sc, _, _ in picked.values()})
    if scenario is not None:
        if scenario not in {sc.name for sc, _, _ in samples}:
            raise InputError(f"{dataset}: no scenario {scenario!r} (it has "
                             f"{', '.join(sorted({sc.name for sc, _, _ in samples}))})")
        picked = {i: s for i, s in picked.items() if s[0].name == scenario}
    elif len(names) > 1:
        raise InputError(f"{folder}: the predictions span scenarios {', '.join(names)}; "
                         "frames are numbered per scenario: choose one (scenario=...)")
    parts, frames, moved = [], [], 0
    for i, (sc, ego, stamp) in sorted(picked.items()):
        path = files[i]
        frame = frame_number(stamp, str(ego / f"{stamp}.yaml"))
        pose, moving = ego_pose(ego, stamp)
        moved += moving
        world = corners_to_world(load_corners(path), pose)
        box = corners_to_boxes(world, str(path))
        parts.append(Boxes(np.full(len(box), frame), box, VEHICLE, 1.0))
        frames.append(frame)
    if moved and notices is not None:
        notices.append(f"{folder}: the ego LiDAR moved during {moved} of its sweeps; its "
                       "predictions are placed with its pose at the sweep start (OPV2V's "
                       "lidar_pose), off by as far as it travelled before it scanned each "
                       "object")
    return Boxes.concat(parts).validate(str(folder)), sorted(frames)


__all__ = ["corners_to_world", "ego_pose", "load_corners", "opv2v_samples",
           "prediction_files", "read_opencood_npy"]

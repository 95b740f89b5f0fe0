"""``rls evaluate`` as users run it, on datasets ``rls dataset`` wrote of a small scene:
a ground plane, cars (one outside the region, one shut in a garage), an InfraLOB, two
LiDARs on poles. The ground truth written out as each detector's files scores 1; a
shifted box scores the IoU its geometry gives; bad input is one error line and no file."""

import json
import math
import os
import pickle
import shutil
import subprocess
import sys

import numpy as np
import pytest

from .conftest import ROOT, SCENE_SCRIPT_HEAD, build_blend, one_line_error, rls

FRAMES = (1, 2)
CLASSES = ["Vehicle", "Pedestrian", "Cyclist"]

BUILD = SCENE_SCRIPT_HEAD + r"""
from rls_addon.blender.scenes.build import box, collection, infralob, plane, standard_materials
scene = bpy.context.scene
mats = standard_materials()
plane(collection(scene, "Road"), "Ground", -60, 60, -60, 60, 0.0, mats["asphalt"], cuts=4)
cars = collection(scene, "Vehicles")
for name, (x, y), (l, w, h) in [("Car A", (8, 3), (4.5, 1.8, 1.5)),
                                ("Car B", (-10, -4), (4.2, 1.8, 1.5)),
                                ("Car C", (15, -5), (4.8, 2.0, 1.6)),
                                ("Car far", (35, 6), (4.5, 1.8, 1.5)),
                                ("Car in garage", (-15, 6), (4.0, 1.8, 1.5))]:
    box(cars, name, (x - l / 2, y - w / 2, 0.0), (x + l / 2, y + w / 2, h), mats["paint"])
box(collection(scene, "Buildings"), "Garage", (-18, 4, 0), (-12, 8, 3), mats["facade"])
infralob(scene, "InfraLOB", -20, 20, -10, 10)
for name, y, yaw in (("Pole N", 12.0, -90.0), ("Pole S", -14.0, 90.0)):
    lidar = bpy.data.objects.new(name, None)
    lidar.location = (0.0, y, 5.0)
    lidar.rotation_euler = (0.0, math.radians(15.0), math.radians(yaw))
    scene.collection.objects.link(lidar)
    lidar.rls_lidar.is_lidar, lidar.rls_lidar.preset_id = True, "velodyne_vlp32c"
scene.frame_start, scene.frame_end = 1, 2
bpy.ops.wm.save_as_mainfile(filepath=sys.argv[2])
"""


@pytest.fixture(scope="module")
def data(tmp_path_factory):
    """The scene, its kitti dataset and its OPV2V dataset (frames 1-2)."""
    folder = tmp_path_factory.mktemp("evaluate")
    blend = build_blend(folder, "street.blend", BUILD)
    for layout in ("kitti", "opv2v"):
        proc = rls("dataset", blend, "--layout", layout, "--frames", "1-2",
                   "--out", folder / layout, "--seed", "1")
        assert proc.returncode == 0, proc.stderr
    return {"blend": blend, "lob": f"{blend}:InfraLOB", "kitti": folder / "kitti",
            "root": folder / "kitti" / "Pole_N", "opv2v": folder / "opv2v"}


def truth_of(root):
    from rls_addon.core.evaluate.ground_truth_files import read_ground_truth

    return read_ground_truth(root)


def evaluate(data, detections, out, *more, truth=None):
    proc = rls("evaluate", "--truth", truth or data["root"], "--detections", detections,
               "--lob", data["lob"], "--out", out, *more)
    assert proc.returncode == 0, proc.stderr
    return json.loads(out.read_text()), proc


# --- the ground truth written as each format's detections -------------------------------

def write_kitti(data, folder):
    from rls_addon.core.evaluate.kitti_labels import write_detections

    boxes = truth_of(data["root"]).boxes
    boxes.score = np.linspace(0.95, 0.5, len(boxes))
    write_detections(folder, boxes, data["root"])
    return folder, []


def write_openpcdet(data, folder):
    """result.pkl as OpenPCDet's tools/test.py pickles det_annos (boxes_lidar in the
    frame of the dataset's points)."""
    from rls_addon.core.evaluate.box_frames import to_frame
    from rls_addon.core.evaluate.kitti_meta import KittiMeta

    meta = KittiMeta.open(data["root"])
    boxes = truth_of(data["root"]).boxes
    annos = []
    for f in FRAMES:
        sel = boxes.frame == f
        names = np.array([{11: "Vehicle", 12: "Pedestrian", 18: "Cyclist"}[int(c)]
                          for c in boxes.label[sel]])
        annos.append({"name": names, "score": np.full(int(sel.sum()), 0.8, np.float32),
                      "boxes_lidar": to_frame(boxes.box[sel], meta.frame_to_world(f))
                      .astype(np.float32),
                      "pred_labels": np.array([CLASSES.index(n) + 1 for n in names]),
                      "frame_id": np.array(f"{f:06d}")})
    folder.mkdir()
    (folder / "result.pkl").write_bytes(pickle.dumps(annos, protocol=4))
    return folder / "result.pkl", []


def write_opencood(data, folder):
    """NNNN_pred.npy as opencood/tools/inference.py --save_npy saves them: (N, 8, 3)
    corners in the ego LiDAR's frame, CARLA's axes (y mirrored), in OpenCOOD's order."""
    from rls_addon.core.evaluate.corners import boxes_to_corners
    from rls_addon.core.evaluate.opencood import ego_pose, opv2v_samples

    boxes = truth_of(data["root"]).boxes
    folder.mkdir()
    for i, (_, ego, stamp) in enumerate(opv2v_samples(data["opv2v"])):
        pose, _ = ego_pose(ego, stamp)
        world = boxes_to_corners(boxes.box[boxes.frame == int(stamp)])
        local = (world - pose[:3, 3]) @ pose[:3, :3]
        local[..., 1] *= -1.0
        np.save(folder / f"{i:04d}_pred.npy", local.astype(np.float32))
    return folder, ["--dataset", data["opv2v"]]


@pytest.mark.parametrize("fmt, write", [("kitti", write_kitti), ("openpcdet", write_openpcdet),
                                        ("opencood", write_opencood)])
def test_ground_truth_as_detections_scores_one_in_every_format(data, tmp_path, fmt, write):
    detections, more = write(data, tmp_path / "det")
    result, proc = evaluate(data, detections, tmp_path / "r.json", *more)
    assert result["inputs"]["format"] == fmt
    g = result["ground_truth"]
    # cars A, B, C in each of 2 frames; the far car outside the region, the one in the
    # garage without points: don't-care
    assert (g["counted"], g["ignored_outside_region"], g["ignored_few_points"]) == (6, 2, 2)
    assert result["region"]["area_m2"] == pytest.approx(800.0)
    vehicle = result["classes"]["vehicle"]["all"]
    for kind in ("bev", "3d"):
        for t in ("0.3", "0.5", "0.7"):
            rec = vehicle[kind][t]
            assert (rec["ap_r40"], rec["ap_voc"]) == (1.0, 1.0), (kind, t)
            assert (rec["tp"], rec["fp"], rec["gt"], rec["missed"], rec["ignored"]) == \
                (6, 0, 6, 0, 4)
    assert result["classes"]["pedestrian"]["all"]["bev"]["0.5"]["ap_r40"] is None
    assert set(result["conventions"]) >= {"ap_r40", "ap_voc"}
    assert [f["frame"] for f in result["frames"]] == [1, 2]
    assert all(f["all"]["gt"] == 3 and f["all"]["3d"]["0.7"]["tp"] == 3
               for f in result["frames"])
    # AP_R40, KITTI's official AP_R40 (as OpenPCDet computes it: with 6 counted boxes it
    # samples 6 recall points and the other 34 of its 40 stay 0, so 5/40), AP_VOC
    assert "vehicle    all        3D  0.7     1.0000  0.1250  1.0000      6      0      6" in \
        proc.stdout


def test_a_box_shifted_along_its_length_scores_the_iou_its_geometry_gives(data, tmp_path):
    from rls_addon.core.evaluate.detections import Boxes
    from rls_addon.core.evaluate.kitti_labels import write_detections

    truth = truth_of(data["root"])
    gt = truth.boxes
    k = int(np.flatnonzero((gt.frame == 1) & (np.abs(gt.box[:, 0] - 8.0) < 0.01))[0])  # car A
    box = gt.box[k].copy()
    length, yaw, d = box[3], box[6], 1.0
    box[:2] += d * np.array([math.cos(yaw), math.sin(yaw)])
    write_detections(tmp_path / "det", Boxes([1], box, [11], [0.9]), data["root"],
                     frames=FRAMES)
    expected = (length - d) / (length + d)  # same width, height and floor: BEV = 3D
    assert abs(expected - 3.5 / 5.5) < 1e-6
    result, _ = evaluate(data, tmp_path / "det", tmp_path / "r.json", "--iou", "0.63,0.64")
    (m,) = result["matches"]
    assert m["best"]["bev"]["iou"] == pytest.approx(expected, abs=2e-6)
    assert m["best"]["3d"]["iou"] == pytest.approx(expected, abs=2e-6)
    assert m["best"]["bev"]["instance"] == int(truth.instance[k])
    assert m["status"] == {"bev": {"0.63": "tp", "0.64": "fp"},
                           "3d": {"0.63": "tp", "0.64": "fp"}}
    rec = result["classes"]["vehicle"]["all"]["bev"]
    assert (rec["0.63"]["tp"], rec["0.63"]["gt"], rec["0.63"]["ap_r40"]) == (1, 6, 0.15)
    assert (rec["0.64"]["tp"], rec["0.64"]["fp"], rec["0.64"]["ap_r40"]) == (0, 1, 0.0)


def test_several_lidars_are_scored_as_one(data, tmp_path):
    from rls_addon.core.evaluate.kitti_labels import write_detections

    north, south = truth_of(data["root"]), truth_of(data["kitti"] / "Pole_S")
    assert north.sensor == "Pole N" and south.sensor == "Pole S"
    write_detections(tmp_path / "det", north.boxes, data["root"])
    # the dataset folder holds both sensors: --dataset says whose frame the boxes are in
    proc = rls("evaluate", "--truth", data["kitti"], "--detections", tmp_path / "det",
               "--out", tmp_path / "r.json")
    assert "give --dataset" in one_line_error(proc)
    assert not (tmp_path / "r.json").exists()
    result, _ = evaluate(data, tmp_path / "det", tmp_path / "r.json", "--dataset",
                         data["root"], truth=data["kitti"])
    assert result["ground_truth"]["sensors"] == ["Pole N", "Pole S"]
    frame = result["frames"][0]
    assert set(frame["sensors"]) == {"Pole N", "Pole S"}
    assert frame["sensors"]["Pole S"]["position"] == pytest.approx([0.0, -14.0, 5.0])
    # each car's points: the sum of both sensors'
    car_a = [m for m in result["matches"] if m["frame"] == 1 and abs(m["box"][0] - 8) < 0.01]
    inst = car_a[0]["best"]["3d"]["instance"]
    points = [t.boxes.points[(t.instance == inst) & (t.boxes.frame == 1)][0]
              for t in (north, south)]
    assert min(points) > 5 and result["ground_truth"]["counted"] == 6
    assert result["classes"]["vehicle"]["all"]["3d"]["0.7"]["ap_r40"] == 1.0
    # the same scans' sidecars (rls scan writes both sensors' into one folder) as truth
    clouds = tmp_path / "clouds"
    assert rls("scan", data["blend"], "--frames", "1-2", "--seed", "1", "--out",
               clouds).returncode == 0
    again, _ = evaluate(data, tmp_path / "det", tmp_path / "again.json", "--dataset",
                        data["root"], truth=clouds)
    assert again["ground_truth"]["sensors"] == ["Pole N", "Pole S"]
    assert again["ground_truth"]["counted"] == 6
    assert again["classes"]["vehicle"]["all"] == result["classes"]["vehicle"]["all"]
    assert again["frames"] == result["frames"]


class Touch:
    def __init__(self, path):
        self.path = path

    def __reduce__(self):
        return (os.system, (f"touch '{self.path}'",))


def test_a_malicious_result_pkl_runs_nothing_and_writes_nothing(data, tmp_path):
    marker = tmp_path / "marker"
    (tmp_path / "det").mkdir()
    annos = [{"name": np.array(["Vehicle"]), "score": np.array([0.9]),
              "boxes_lidar": np.zeros((1, 7)) + 1, "frame_id": "000001",
              "metadata": Touch(marker)}]
    (tmp_path / "det" / "result.pkl").write_bytes(pickle.dumps(annos))
    proc = rls("evaluate", "--truth", data["root"], "--detections",
               tmp_path / "det" / "result.pkl", "--out", tmp_path / "r.json")
    line = one_line_error(proc)
    assert "refused to load: it names posix.system" in line
    assert not marker.exists() and not (tmp_path / "r.json").exists()


def another_scene(root, to, scene):
    """A copy of the kitti sensor root ``root`` as a dataset of ``scene`` would name it
    (its dataset.json and every frame's meta): what matters to the identity check."""
    shutil.copytree(root, to)
    for f in [to / "dataset.json", *sorted((to / "meta").glob("*.json"))]:
        body = json.loads(f.read_text())
        body["scene"] = scene
        f.write_text(json.dumps(body))
    return to


def test_detect_refuses_a_bad_noise_sigma_and_datasets_of_two_scenes(data, tmp_path):
    """--noise-sigma nan and -1 were taken and changed nothing (issue 38)."""
    for bad in ("nan", "-1", "inf", "5"):
        line = one_line_error(rls("detect", data["root"], "--out", tmp_path / "d",
                                  "--noise-sigma", bad))
        assert "--noise-sigma must be the device's range noise in metres, from 0 to 1" in line
    other = another_scene(data["kitti"] / "Pole_S", tmp_path / "other" / "Pole_S", "intersection")
    line = one_line_error(rls("detect", data["root"], other, "--out", tmp_path / "d"))
    assert f"{data['root']} is a dataset of scene 'Scene' and {other} of scene" in line
    assert not (tmp_path / "d").exists()


def label_folder(tmp_path, text, frame=1):
    folder = tmp_path / "det"
    folder.mkdir(exist_ok=True)
    (folder / f"{frame:06d}.txt").write_text(text)
    return folder


CAR = "10.0 2.0 -4.0 4.5 1.8 1.5 0.0"


@pytest.mark.parametrize("case, message", [
    ("frame_not_in_dataset", "frame 9 is not in the dataset"),
    ("frame_not_in_truth", "detections for frames 2 that the ground truth does not have "
                           "(it has frames 1)"),
    ("nan", "a NaN or infinite value"),
    ("negative", "sizes dx dy dz must be above zero"),
    ("unknown_class", "unknown class 'Tram': RLS evaluates vehicle, pedestrian, cyclist"),
    ("unknown_score_class", "unknown class 'tram': RLS evaluates vehicle, pedestrian, cyclist"),
    ("empty", "no detections found"),
    ("no_truth_in_region", "no ground-truth box with >= 5 points has its centre inside the "
                           "region; of 5 boxes"),
    ("degenerate_region", "region outline has zero area"),
    ("existing_out", "already exists; pass --overwrite to replace it"),
    # issue 38: AP 0 before, without a word
    ("other_scene", "is a dataset of scene 'Scene' and --dataset "),
    # issue 38: scored before, with an overflow warning from the overlap
    ("far_box", "000001.txt, line 1: a box centre at 1e+308 2.0 -4.0 m, farther than"),
    ("huge_heading", "000001.txt, line 1: heading 1e+30 rad is not an angle"),
])
def test_bad_input_is_one_error_line_and_no_file(data, tmp_path, case, message):
    out = tmp_path / "r.json"
    truth, more = data["root"], []
    det = label_folder(tmp_path, f"{CAR} Vehicle 0.9\n")
    if case == "frame_not_in_dataset":
        label_folder(tmp_path, f"{CAR} Vehicle 0.9\n", frame=9)
    elif case == "frame_not_in_truth":
        truth = tmp_path / "truth"
        shutil.copytree(data["root"], truth)
        (truth / "meta" / "000002.json").unlink()
        label_folder(tmp_path, "", frame=2)
        more = ["--dataset", data["root"]]
    elif case == "nan":
        det = label_folder(tmp_path, "10 2 -4 nan 1.8 1.5 0 Vehicle 0.9\n")
    elif case == "negative":
        det = label_folder(tmp_path, "10 2 -4 4.5 -1.8 1.5 0 Vehicle 0.9\n")
    elif case == "unknown_class":
        det = label_folder(tmp_path, f"{CAR} Tram 0.9\n")
    elif case == "unknown_score_class":
        more = ["--classes", "vehicle,tram"]
    elif case == "empty":
        shutil.rmtree(det)
        det.mkdir()
    elif case == "no_truth_in_region":
        more = ["--region", "100,100 110,100 110,110 100,110"]
    elif case == "degenerate_region":
        more = ["--region", "0,0 1,1 2,2"]
    elif case == "existing_out":
        out.write_text("keep")
    elif case == "other_scene":  # the same frames, written from another scene
        other = another_scene(data["root"], tmp_path / "other" / "Pole_N", "intersection")
        more = ["--dataset", other]
    elif case == "far_box":
        det = label_folder(tmp_path, "1e308 2 -4 4.5 1.8 1.5 0 Vehicle 0.9\n")
    elif case == "huge_heading":
        det = label_folder(tmp_path, "10 2 -4 4.5 1.8 1.5 1e30 Vehicle 0.9\n")
    proc = rls("evaluate", "--truth", truth, "--detections", det, "--out", out, *more)
    assert message in one_line_error(proc)
    assert proc.stdout == ""
    if case == "existing_out":
        assert out.read_text() == "keep"
    else:
        assert not out.exists()


def test_evaluate_without_lob_never_imports_blender(data, tmp_path):
    det = label_folder(tmp_path, f"{CAR} Vehicle 0.9\n")
    script = ("import sys; import tests.no_blender; from rls_addon.cli import main; "
              "code = main(sys.argv[1:]); "
              "assert not any(m.split('.')[0] == 'bpy' for m in sys.modules); sys.exit(code)")
    proc = subprocess.run([sys.executable, "-c", script, "evaluate", "--truth", data["root"],
                           "--detections", det, "--region", "-20,-10 20,-10 20,10 -20,10",
                           "--distance-bins", "0,15,inf"],
                          cwd=ROOT, env=dict(os.environ, PYTHONPATH=str(ROOT)),
                          capture_output=True, text=True, timeout=120)
    assert proc.returncode == 0, proc.stderr
    assert "vehicle    0-15 m     BEV 0.5" in proc.stdout

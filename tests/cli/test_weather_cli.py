"""``rls scan --weather``: fog dims and loses far returns and adds false returns near the
sensor, labelled 'weather', and the sidecar records the weather and the device's
detection model."""


import numpy as np
import pytest

from .conftest import SCENE_SCRIPT_HEAD, build_blend, one_line_error, rls

BUILD = SCENE_SCRIPT_HEAD + r"""
scene = bpy.context.scene
scene.name = "foggy"

box("Ground", (-10, -40, -1.6), (90, 40, -1.5), 0.2, "road")
box("Wall", (60, -40, -1.5), (61, 40, 30), 0.5, "wall")
lidar = bpy.data.objects.new("LiDAR", None)
scene.collection.objects.link(lidar)
s = lidar.rls_lidar
s.is_lidar, s.preset_id, s.noise = True, "livox_mid40", False
s.file_format, s.fields = "pcd_binary", {"intensity", "range", "label", "instance"}
s.output_dir = sys.argv[3]
bpy.ops.wm.save_as_mainfile(filepath=sys.argv[2])
"""


@pytest.fixture(scope="module")
def foggy_blend(tmp_path_factory):
    d = tmp_path_factory.mktemp("foggy")
    return build_blend(d, "foggy.blend", BUILD, d / "panel")


def _scan(blend, out, *flags):
    proc = rls("scan", blend, "--frames", "1", "--out", out, *flags)
    assert proc.returncode == 0, proc.stderr[-3000:]
    from rls_addon.core.output.io import read_cloud, read_sidecar

    cloud = out / "foggy_LiDAR_000001.pcd"
    return read_cloud(cloud), read_sidecar(cloud)


def test_fog_loses_far_returns_and_adds_weather_points_near_the_sensor(foggy_blend, tmp_path):
    clear, clear_side = _scan(foggy_blend, tmp_path / "clear")
    fog, fog_side = _scan(foggy_blend, tmp_path / "fog", "--weather", "fog:visibility=30")
    far_clear = np.count_nonzero(clear["range"] > 40)
    far_fog = np.count_nonzero(fog["range"] > 40)
    assert far_clear > 500 and far_fog < far_clear / 10, (far_clear, far_fog)
    assert not np.any(clear["label"] == 19)
    air = fog[fog["label"] == 19]
    assert len(air) > 100 and np.all(air["instance"] == 0)
    assert np.median(air["range"]) < 3.0 and air["range"].min() >= 1.0 - 1e-3
    assert clear_side["effects"]["weather"] is None
    w = fog_side["effects"]["weather"]
    assert w["spec"] == "fog:visibility=30" and w["kind"] == "fog"
    assert fog_side["weather_returns"] == len(air)
    det = fog_side["device"]["detection"]
    assert det["model"] == "lidar_equation" and det["range_at_reflectivity"] == [[0.1, 90.0],
                                                                                [0.8, 260.0]]
    # the model switched off: every hit within range returns, as before
    carla, carla_side = _scan(foggy_blend, tmp_path / "carla", "--detection", "carla")
    assert carla_side["device"]["detection"]["model"] == "carla"
    assert len(carla) >= len(clear)


def test_a_bad_weather_spec_is_one_error(foggy_blend, tmp_path):
    proc = rls("scan", foggy_blend, "--frames", "1", "--out", tmp_path, "--weather",
               "fog:visibility=-3")
    line = one_line_error(proc)
    assert "--weather" in line and "visibility must be a number" in line
    assert not list(tmp_path.glob("*.pcd"))

"""``rls scene from-net``'s core entry point: settings in, a builder handed in, progress
from the first seconds (issue #38: a 30 x 30 grid printed nothing for 52 s), a quick
refusal with no progress line."""

import time

import pytest

from rls_addon.core.errors import InputError
from rls_addon.core.roads import scene as roads_scene
from rls_addon.core.roads.scene import FromNetSettings, scene_from_net
from tests.sumo_nets import grid_net


class FakeBuilder:
    def __init__(self):
        self.saved = None

    def build(self, layout, say, tiles):
        for done in range(1, 4):
            tiles(done, 3, 0.0)
        return {"junction": layout.junction.id}

    def save(self, out, overwrite):
        self.saved = (out, overwrite)


def test_the_reading_is_reported_while_it_runs(tmp_path, monkeypatch):
    """sumolib's read made slow (3.5 s): its stage is said after a second and its time
    every two, from another thread, before the read returns."""
    net = grid_net(tmp_path)
    real = roads_scene.read_network
    heard = []

    def slow(path):
        time.sleep(3.5)
        heard.append("read returned")
        return real(path)

    monkeypatch.setattr(roads_scene, "read_network", slow)
    builder = FakeBuilder()
    info = scene_from_net(FromNetSettings(str(net), str(tmp_path / "s.blend")),
                          lambda: builder, heard.append)
    before = heard[:heard.index("read returned")]
    assert before[0].startswith("reading ") and "MB) with sumolib" in before[0]
    assert any(h.startswith("reading: ") and h.endswith("s so far") for h in before)
    assert info["junction"] == "B1" and builder.saved == (str(tmp_path / "s.blend"), False)
    assert any(h.startswith("triangulating: tile 3 of 3") for h in heard)


def test_a_quick_refusal_says_nothing_else(tmp_path):
    net = grid_net(tmp_path)
    heard = []
    with pytest.raises(InputError, match="no junction 'Z9'"):
        scene_from_net(FromNetSettings(str(net), str(tmp_path / "s.blend"), junction="Z9"),
                       lambda: pytest.fail("Blender is not started for a refused input"),
                       heard.append)
    assert heard == []

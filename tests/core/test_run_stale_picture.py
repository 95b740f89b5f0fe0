"""A frame written again without --preview-png: the picture an earlier run drew of it
(named by the sidecar this write replaces) is removed once the new files are in place,
so no picture is left that shows points the frame no longer holds; a picture no
sidecar names (the user's, or one drawn before sidecars named theirs) is kept."""

import json

import pytest

from rls_addon.core.errors import OutputError
from rls_addon.core.output.io import read_sidecar

from .fakes import street
from .test_run import job, run_of
from .test_run_other_format import refuse_removal


def _names(folder):
    return sorted(p.name for p in folder.iterdir())


def _frames(folder, exts, frames=(1, 2)):
    return [f"fake_pole_{f:06d}.{e}" for f in frames for e in exts]


@pytest.mark.parametrize("again", [{"overwrite": True}, {"resume": True}])
def test_an_earlier_runs_picture_goes_with_the_frame_written_again(tmp_path, again):
    scene = street()
    run_of(scene, [job("pole", tmp_path)], [1, 2], tmp_path, writer_kw={"preview": True}).run()
    assert _names(tmp_path) == sorted(["fake_instances.json"]
                                      + _frames(tmp_path, ("pcd", "json", "png")))
    assert read_sidecar(tmp_path / "fake_pole_000001.pcd")["picture"] == "fake_pole_000001.png"
    # a resumed run keeps frame 1 as it is (its picture too) and scans frame 2 again
    if "resume" in again:
        side = tmp_path / "fake_pole_000002.json"
        side.write_text(json.dumps(dict(json.loads(side.read_text()), points=-1)))
    run_of(scene, [job("pole", tmp_path)], [1, 2], tmp_path, writer_kw=again).run()
    kept = ["fake_pole_000001.png"] if "resume" in again else []
    assert _names(tmp_path) == sorted(["fake_instances.json"] + kept
                                      + _frames(tmp_path, ("pcd", "json")))
    assert "picture" not in read_sidecar(tmp_path / "fake_pole_000002.pcd")


def test_a_picture_no_sidecar_names_is_kept_and_a_new_one_is_named(tmp_path):
    scene = street()
    run_of(scene, [job("pole", tmp_path)], [1], tmp_path).run()
    (tmp_path / "fake_pole_000001.png").write_bytes(b"a user's picture")
    run_of(scene, [job("pole", tmp_path)], [1], tmp_path,
           writer_kw={"overwrite": True}).run()
    assert (tmp_path / "fake_pole_000001.png").read_bytes() == b"a user's picture"
    # drawn again with --preview-png: replaced, and named by the new sidecar
    run_of(scene, [job("pole", tmp_path)], [1], tmp_path,
           writer_kw={"overwrite": True, "preview": True}).run()
    assert (tmp_path / "fake_pole_000001.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert read_sidecar(tmp_path / "fake_pole_000001.pcd")["picture"] == "fake_pole_000001.png"


def test_a_picture_that_cannot_be_removed_is_an_error_naming_it(tmp_path, monkeypatch):
    scene = street()
    run_of(scene, [job("pole", tmp_path)], [1], tmp_path, writer_kw={"preview": True}).run()
    refuse_removal(monkeypatch, "fake_pole_000001.png")
    with pytest.raises(OutputError, match="cannot remove .*fake_pole_000001.png, the picture "
                                          "of an earlier run with --preview-png"):
        run_of(scene, [job("pole", tmp_path)], [1], tmp_path,
               writer_kw={"overwrite": True}).run()
    # the new frame is complete: its cloud and the sidecar that describes it
    assert "picture" not in read_sidecar(tmp_path / "fake_pole_000001.pcd")


def test_a_resumed_run_with_pictures_scans_again_a_frame_without_its_picture(tmp_path):
    scene = street()
    run_of(scene, [job("pole", tmp_path)], [1, 2], tmp_path).run()
    (tmp_path / "fake_pole_000002.png").write_bytes(b"a user's picture")
    run = run_of(scene, [job("pole", tmp_path)], [1, 2], tmp_path,
                 writer_kw={"resume": True, "preview": True}).run()
    # frame 1 has no picture: scanned again and drawn; frame 2's picture, which its
    # sidecar does not name, is not the run's: scanned again and drawn over it
    assert run.resumed == 0 and run.scanned == 2
    for f in (1, 2):
        assert (tmp_path / f"fake_pole_{f:06d}.png").read_bytes()[:4] == b"\x89PNG"
    again = run_of(scene, [job("pole", tmp_path)], [1, 2], tmp_path,
                   writer_kw={"resume": True, "preview": True}).run()
    assert again.resumed == 2 and again.scanned == 0

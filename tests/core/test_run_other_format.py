"""A frame written again in another format ('x.pcd', then 'x.ply' with --overwrite or
--resume): both share the sidecar 'x.json', so the earlier cloud, which that sidecar no
longer describes, is removed once the new files are in place; nothing else is."""

import os

import pytest

from rls_addon.core.errors import OutputError
from rls_addon.core.output.io import read_cloud, read_sidecar
from rls_addon.core.scan.run import SensorJob

from .fakes import street
from .test_run import PRESET, job, run_of


def _as(out, fmt):
    j = job("pole", out)
    return SensorJob("pole", j.settings.override(format=fmt), PRESET)


def _names(folder):
    return sorted(p.name for p in folder.iterdir())


@pytest.mark.parametrize("again", [{"overwrite": True}, {"resume": True}])
def test_the_earlier_cloud_in_another_format_is_removed(tmp_path, again):
    scene = street()
    run_of(scene, [_as(tmp_path, "pcd_binary")], [1, 2], tmp_path).run()
    (tmp_path / "notes.pcd").write_text("a user's file")  # not a frame's: left alone
    run = run_of(scene, [_as(tmp_path, "ply_binary")], [1, 2], tmp_path, writer_kw=again)
    said = [n for n in run.notices if "another format" in n]
    assert len(said) == 1 and said[0].startswith("2 file(s) of another format (.pcd)")
    assert "removed once its frame's new files are written" in said[0]
    run.run()
    assert _names(tmp_path) == sorted(["fake_instances.json", "notes.pcd"] + [
        f"fake_pole_{f:06d}.{e}" for f in (1, 2) for e in ("ply", "json")])
    side = read_sidecar(tmp_path / "fake_pole_000001.ply")
    assert side["format"] == "ply_binary"
    assert len(read_cloud(tmp_path / "fake_pole_000001.ply")) == side["points"]


def test_the_same_format_again_and_a_cloud_no_sidecar_names_are_kept(tmp_path):
    scene = street()
    run_of(scene, [_as(tmp_path, "pcd_binary")], [1], tmp_path).run()
    # a .ply of the same name that the sidecar does not describe (the user's): kept
    (tmp_path / "fake_pole_000001.ply").write_text("a user's file")
    run = run_of(scene, [_as(tmp_path, "pcd_ascii")], [1], tmp_path,
                 writer_kw={"overwrite": True})
    assert [n for n in run.notices if "another format" in n] == [
        f"1 file(s) of another format (.ply) beside this run's outputs, e.g. "
        f"{tmp_path / 'fake_pole_000001.ply'}: left as they are (no sidecar here describes them)"]
    run.run()
    assert (tmp_path / "fake_pole_000001.ply").read_text() == "a user's file"
    assert read_sidecar(tmp_path / "fake_pole_000001.pcd")["format"] == "pcd_ascii"


def refuse_removal(monkeypatch, name):
    """The writer's removal of a file named ``name`` fails (permission denied)."""
    from rls_addon.core.output.io import writer as writer_mod

    unlink = os.unlink

    def refused(path, *a, **k):
        if str(path).endswith(name):
            raise PermissionError(13, "Permission denied")
        return unlink(path, *a, **k)

    monkeypatch.setattr(writer_mod.os, "unlink", refused)


def test_an_earlier_cloud_that_cannot_be_removed_is_an_error_naming_it(tmp_path, monkeypatch):
    scene = street()
    run_of(scene, [_as(tmp_path, "pcd_binary")], [1], tmp_path).run()
    refuse_removal(monkeypatch, "fake_pole_000001.pcd")
    with pytest.raises(OutputError, match="cannot remove .*fake_pole_000001.pcd"):
        run_of(scene, [_as(tmp_path, "ply_binary")], [1], tmp_path,
               writer_kw={"overwrite": True}).run()
    # the new frame is complete: its cloud and the sidecar that describes it
    assert read_sidecar(tmp_path / "fake_pole_000001.ply")["format"] == "ply_binary"

"""Atomic writes, overwrite protection, output templates, sidecars, clear errors."""

import json
import os
import pathlib

import numpy as np
import pytest

from rls_addon.core.errors import InputError, OutputError
from rls_addon.core.output.io import (
    FORMATS,
    atomic_write_bytes,
    output_path,
    read_cloud,
    read_sidecar,
    write_cloud,
    write_sidecar,
)
from rls_addon.core.output.io import atomic as atomic_mod

from .cloud_samples import sample_cloud


def _leftovers(directory):
    return sorted(p.name for p in pathlib.Path(directory).iterdir() if p.name.endswith(".tmp"))


def test_writes_create_parent_directories(tmp_path):
    path = write_cloud(tmp_path / "a" / "b" / "c.pcd", sample_cloud(5))
    assert path.is_file() and len(read_cloud(path)) == 5


def test_failure_mid_write_leaves_no_file_and_no_temp(tmp_path):
    target = tmp_path / "out.pcd"

    def writer(fh):
        fh.write(b"half a file")
        raise RuntimeError("boom")

    with pytest.raises(RuntimeError):
        atomic_write_bytes(target, writer)
    assert not target.exists()
    assert list(tmp_path.iterdir()) == []


def test_keyboard_interrupt_mid_write_cleans_up(tmp_path):
    target = tmp_path / "out.ply"

    def writer(fh):
        fh.write(b"x" * 1000)
        raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt):
        atomic_write_bytes(target, writer)
    assert list(tmp_path.iterdir()) == []


def test_failed_rewrite_keeps_the_old_file(tmp_path):
    target = tmp_path / "out.pcd"
    write_cloud(target, sample_cloud(3))
    before = target.read_bytes()

    def writer(fh):
        fh.write(b"garbage")
        raise RuntimeError("boom")

    with pytest.raises(RuntimeError):
        atomic_write_bytes(target, writer, overwrite=True)
    assert target.read_bytes() == before
    assert _leftovers(tmp_path) == []


def test_no_overwrite_without_permission(tmp_path):
    target = tmp_path / "f.ply"
    write_cloud(target, sample_cloud(3), "ply_binary")
    before = target.read_bytes()
    with pytest.raises(OutputError, match="--overwrite") as info:
        write_cloud(target, sample_cloud(4), "ply_binary")
    assert str(target) in str(info.value)
    assert target.read_bytes() == before
    write_cloud(target, sample_cloud(4), "ply_binary", overwrite=True)
    assert len(read_cloud(target)) == 4
    assert _leftovers(tmp_path) == []


def test_target_appearing_during_write_is_not_clobbered(tmp_path):
    target = tmp_path / "race.pcd"

    def writer(fh):
        target.write_bytes(b"someone else")
        fh.write(b"ours")

    with pytest.raises(OutputError, match="already exists"):
        atomic_write_bytes(target, writer)
    assert target.read_bytes() == b"someone else"
    assert _leftovers(tmp_path) == []


def test_directory_under_a_regular_file_is_a_clear_error(tmp_path):
    blocker = tmp_path / "file"
    blocker.write_text("not a directory")
    with pytest.raises(OutputError, match="cannot create directory"):
        write_cloud(blocker / "sub" / "c.pcd", sample_cloud(2))
    # the file itself where the folder should be: said so, not "File exists"
    with pytest.raises(OutputError, match="cannot create directory .*file: a file is in the way"):
        write_cloud(blocker / "c.pcd", sample_cloud(2))


def test_unwritable_location_is_a_clear_error():
    with pytest.raises(OutputError, match="cannot"):
        write_cloud("/proc/rls-test/c.pcd", sample_cloud(2))


def test_disk_full_is_reported(tmp_path, monkeypatch):
    def full(*a, **k):
        raise OSError(28, "No space left on device")

    monkeypatch.setattr(atomic_mod.os, "fsync", full)
    with pytest.raises(OutputError, match="disk full"):
        write_cloud(tmp_path / "c.pcd", sample_cloud(2))
    assert list(tmp_path.iterdir()) == []


@pytest.mark.skipif(not os.path.exists("/dev/full"), reason="needs /dev/full")
def test_dev_full_gives_disk_full_error(tmp_path, monkeypatch):
    real_fdopen = os.fdopen

    def fdopen_full(fd, mode="r", *a, **k):
        os.close(fd)
        return open("/dev/full", mode, buffering=0)

    monkeypatch.setattr(atomic_mod.os, "fdopen", fdopen_full)
    with pytest.raises(OutputError, match="disk full"):
        atomic_write_bytes(tmp_path / "c.bin", b"x" * 100)
    monkeypatch.setattr(atomic_mod.os, "fdopen", real_fdopen)
    assert _leftovers(tmp_path) == []


def test_writing_onto_a_directory_is_refused(tmp_path):
    (tmp_path / "d.pcd").mkdir()
    with pytest.raises(OutputError, match="directory"):
        write_cloud(tmp_path / "d.pcd", sample_cloud(1), overwrite=True)


def test_unknown_format_and_field_are_settings_errors_naming_the_choices(tmp_path):
    from rls_addon.core.errors import SettingsError

    with pytest.raises(SettingsError, match="unknown cloud format 'e57'; choose one of "
                                            "pcd_binary, .*ply_ascii, las, mcap"):
        write_cloud(tmp_path / "c.e57", sample_cloud(1), "e57")
    with pytest.raises(SettingsError, match="written by the scan run's writers"):
        write_cloud(tmp_path / "c.las", sample_cloud(1), "las")
    with pytest.raises(SettingsError, match="unknown point field"):
        write_cloud(tmp_path / "c.pcd", sample_cloud(1), fields=["x", "colour"])


def test_reading_garbage_is_input_error(tmp_path):
    bad = tmp_path / "bad.pcd"
    bad.write_bytes(b"hello")
    with pytest.raises(InputError, match=r"bad.pcd is not a point cloud file RLS reads "
                                         r"\(.pcd, .ply\): it starts with b'hello', not a PCD "
                                         r"header or 'ply'"):
        read_cloud(bad)
    for blob, said in ((b"", "it is empty"), (b" \n\t\n", "it holds nothing but white space")):
        bad.write_bytes(blob)
        with pytest.raises(InputError, match=f"bad.pcd .*: {said}$"):
            read_cloud(bad)
    with pytest.raises(InputError, match="cannot read"):
        read_cloud(tmp_path / "missing.ply")
    truncated = tmp_path / "t.ply"
    truncated.write_bytes(write_cloud(tmp_path / "ok.ply", sample_cloud(10), "ply_binary").read_bytes()[:-5])
    with pytest.raises(InputError):
        read_cloud(truncated)
    # a compressed PCD cut inside its sizes: struct's error, one InputError
    blob = write_cloud(tmp_path / "c.pcd", sample_cloud(10), "pcd_binary_compressed").read_bytes()
    cut = tmp_path / "cut.pcd"
    cut.write_bytes(blob[:blob.index(b"DATA binary_compressed\n") + 26])
    with pytest.raises(InputError, match="cut.pcd is not a readable PCD point cloud"):
        read_cloud(cut)


# ---- output templates -------------------------------------------------------


@pytest.mark.parametrize("fmt", [f.id for f in FORMATS if f.extension])
def test_output_path_renders_and_appends_extension(tmp_path, fmt):
    p = output_path(tmp_path, "{scene}/{sensor}/{frame:06d}", scene="Street 1", sensor="Pandar64.L", frame=7, fmt=fmt)
    assert p == tmp_path / "Street_1" / "Pandar64.L" / f"000007{FORMATS.get(fmt).extension}"


def test_output_path_keeps_matching_extension(tmp_path):
    p = output_path(tmp_path, "{frame}.pcd", scene="s", sensor="l", frame=3, fmt="pcd_binary")
    assert p.name == "3.pcd"
    with pytest.raises(OutputError, match="writes .pcd"):
        output_path(tmp_path, "{frame}.ply", scene="s", sensor="l", frame=3, fmt="pcd_binary")


@pytest.mark.parametrize("name", ["..", "../..", "a/../../b", "..\\x", "/etc/passwd", "~"])
def test_names_cannot_escape(tmp_path, name):
    p = output_path(tmp_path, "{scene}_{sensor}/{frame}", scene=name, sensor=name, frame=0, fmt="ply_binary")
    assert os.path.commonpath([tmp_path, p]) == str(tmp_path)
    assert len(p.relative_to(tmp_path).parts) == 2


@pytest.mark.parametrize("template", ["../{frame}", "{scene}/../../{frame}", "/tmp/{frame}", "a/../../{frame}", "..", "C:\\x\\{frame}"])
def test_templates_escaping_the_directory_are_rejected(tmp_path, template):
    with pytest.raises(OutputError):
        output_path(tmp_path, template, scene="s", sensor="l", frame=1, fmt="pcd_ascii")


@pytest.mark.parametrize("template", ["{frames}", "{scene", "{0}", "", "dir/",
                                      "{frame.__class__}", "{scene[0]}_{frame}", "{}"])
def test_bad_templates_are_output_errors(tmp_path, template):
    with pytest.raises(OutputError):
        output_path(tmp_path, template, scene="s", sensor="l", frame=1, fmt="pcd_ascii")


# ---- sidecars -----------------------------------------------------------------


def test_sidecar_round_trip_with_numpy_values(tmp_path):
    cloud = write_cloud(tmp_path / "000001.pcd", sample_cloud(3))
    info = {"frame": "sensor", "sensor_to_world": np.eye(4), "seed": np.int64(5), "nan": float("nan")}
    side = write_sidecar(cloud, info)
    assert side == tmp_path / "000001.json"
    data = json.loads(side.read_text())
    assert data["sensor_to_world"][0] == [1.0, 0.0, 0.0, 0.0]
    assert data["seed"] == 5 and data["nan"] is None
    assert read_sidecar(cloud) == data
    with pytest.raises(OutputError, match="--overwrite"):
        write_sidecar(cloud, info)
    assert read_sidecar(tmp_path / "other.pcd") is None


def test_a_sidecar_another_formats_run_replaced_is_not_read_for_the_cloud_left(tmp_path):
    """'x.pcd' and 'x.ply' share 'x.json': after 'rls scan --format ply_binary
    --frame-space world --overwrite' over a PCD run, rls metrics read the PCD's
    sensor-frame points with the PLY's world-frame sidecar (InfraD 1.6 for 14.7)."""
    pcd = write_cloud(tmp_path / "s_000001.pcd", sample_cloud(3))
    write_sidecar(pcd, {"format": "pcd_binary", "frame_space": "sensor", "points": 3})
    assert read_sidecar(pcd)["frame_space"] == "sensor"
    write_sidecar(tmp_path / "s_000001.ply", {"format": "ply_binary", "frame_space": "world",
                                              "points": 3}, overwrite=True)
    assert read_sidecar(tmp_path / "s_000001.ply")["frame_space"] == "world"
    with pytest.raises(InputError, match=r"describes a ply_binary cloud \(s_000001\.ply\), "
                                         r"not s_000001\.pcd"):
        read_sidecar(pcd)
    # a sidecar without a format (another tool's, older runs) is read as before
    write_sidecar(pcd, {"frame_space": "sensor"}, overwrite=True)
    assert read_sidecar(pcd) == {"frame_space": "sensor"}


def test_sidecar_rejects_unserialisable(tmp_path):
    with pytest.raises(OutputError, match="JSON"):
        write_sidecar(tmp_path / "c.pcd", {"x": object()})
    assert list(tmp_path.iterdir()) == []


def test_a_set_of_files_is_written_whole_or_not_at_all(tmp_path, monkeypatch):
    """Issue 31: a failed study report left some of its files. A full disk on the third
    file of a set leaves none of the set and no temporary."""
    files = {tmp_path / f"{n}.txt": n.encode() * 10 for n in ("a", "b", "c", "d")}
    real_fdopen, calls = os.fdopen, []

    def failing_fdopen(fd, *a, **k):
        calls.append(fd)
        if len(calls) == 3:
            os.close(fd)
            raise OSError(28, "No space left on device")
        return real_fdopen(fd, *a, **k)

    monkeypatch.setattr(atomic_mod.os, "fdopen", failing_fdopen)
    with pytest.raises(OutputError, match="disk full.*c.txt"):
        atomic_mod.atomic_write_files(files)
    assert sorted(os.listdir(tmp_path)) == []
    monkeypatch.setattr(atomic_mod.os, "fdopen", real_fdopen)
    written = atomic_mod.atomic_write_files(files)
    assert [p.read_bytes() for p in written] == list(files.values())
    with pytest.raises(OutputError, match="already exists"):  # checked before any write
        atomic_mod.atomic_write_files({tmp_path / "new.txt": b"x", tmp_path / "a.txt": b"y"})
    assert not (tmp_path / "new.txt").exists() and (tmp_path / "a.txt").read_bytes() == b"a" * 10


def test_the_sidecar_check_knows_every_formats_extension():
    from rls_addon.core.output.io.formats import FORMATS
    from rls_addon.core.output.io.sidecar import _check_sidecar_format

    for fmt in FORMATS:
        if not fmt.extension:
            continue
        cloud = pathlib.Path("c" + fmt.extension)
        _check_sidecar_format({"format": fmt.id}, "c.json", cloud)  # its own: read
        with pytest.raises(InputError, match="describes a"):
            _check_sidecar_format({"format": fmt.id}, "c.json", pathlib.Path("c.other"))

"""A driving sensor's step leaves its cast under way while the next step starts
(``ScanRun.step``, ``ScanSession.scan_started``): the casts overlap the steps' own work
(the Blender frame change, the read, the sweep) on a 2-core machine. What a run writes
is the same bytes as with every step ended before the next begins (``overlap`` off);
steps end in the plan's order; a still sensor's steps never overlap (its next frame
reuses its static cast); a cancel, a failure or Ctrl+C in the next step's start ends
the step under way first, its files written."""

import pytest

from rls_addon.core.scan.run import ScanRun

from .fakes import street, translation
from .test_run import job, run_of


def drive(speed=9.0):
    scene = street(car_speed=6.0)
    scene.sensors["mast"] = lambda s: translation((-3.0 + speed * s, 2.0, 1.0))
    scene.moving_sensors = ("mast",)
    return scene


def files(folder):
    return {p.name: p.read_bytes() for p in sorted(folder.iterdir())}


def logged(scene, log):
    """``scene`` with its frame changes logged in ``log``."""
    set_frame = scene.set_frame
    scene.set_frame = lambda f: log.append(("frame", f)) or set_frame(f)
    return scene


@pytest.mark.parametrize("sensors", [("mast",), ("mast", "pole")])
def test_overlapped_steps_write_the_same_files(tmp_path, monkeypatch, sensors):
    outs = {}
    for overlap in (False, True):
        monkeypatch.setattr(ScanRun, "overlap", overlap)
        out = tmp_path / str(overlap)
        out.mkdir()
        steps = []
        run = run_of(drive(), [job(s, out, seed=5) for s in sensors], [1, 2, 3, 4], out,
                     progress=steps.append).run()
        assert run.scanned == 4 * len(sensors) and not run.cancelled
        assert [(s.frame, s.sensor) for s in steps] == [(f, s) for f in (1, 2, 3, 4)
                                                        for s in sensors]
        assert [s.done for s in steps] == list(range(1, 4 * len(sensors) + 1))
        outs[overlap] = files(out)
    assert outs[True].keys() == outs[False].keys() and len(outs[True]) > 8
    # every cloud the same bytes; the sidecars too, but for the seconds spent
    for name, data in outs[True].items():
        if name.endswith(".pcd"):
            assert data == outs[False][name], name


def test_a_driving_sensors_step_ends_after_the_next_one_starts(monkeypatch):
    from rls_addon.core.scan import run as run_module

    log = []
    real = run_module.finished
    monkeypatch.setattr(run_module, "finished",
                        lambda steps: log.append(("end", scene.frame)) or real(steps))
    scene = logged(drive(), log)
    run_of(scene, [job("mast")], [1, 2, 3]).run()
    # frame 1's step ends once the scene is at frame 2 (its scan under way meanwhile)
    assert log == [("frame", 1), ("frame", 2), ("end", 2), ("frame", 3), ("end", 3),
                   ("end", 3), ("frame", 1)]  # (the run puts the scene back at frame 1)
    log.clear()
    scene = logged(street(car_speed=6.0), log)  # a still sensor: one step at a time
    run_of(scene, [job("pole")], [1, 2, 3]).run()
    assert log == [("frame", 1), ("end", 1), ("frame", 2), ("end", 2), ("frame", 3),
                   ("end", 3), ("frame", 1)]


def test_a_cancel_or_a_failure_ends_the_step_under_way_first(tmp_path):
    scene = drive()
    asked = []

    def cancel_at_the_third_step():
        asked.append(scene.frame)
        return len(asked) == 3  # asked before each step's scan starts

    run = run_of(scene, [job("mast", tmp_path)], [1, 2, 3, 4], tmp_path,
                 cancelled=cancel_at_the_third_step)
    run.run()
    assert asked == [1, 2, 3]
    assert run.cancelled and run.scanned == 2
    written = sorted(p.name for p in tmp_path.glob("*.pcd"))
    assert written == ["fake_mast_000001.pcd", "fake_mast_000002.pcd"]
    # a failure in frame 3's read: frame 2's step ends, its files written, then it raises
    out = tmp_path / "failed"
    out.mkdir()
    scene = drive()
    read = scene.read

    def failing(centre, max_range, exclude):
        if scene.frame == 3:
            raise KeyboardInterrupt
        return read(centre, max_range, exclude)

    scene.read = failing
    run = run_of(scene, [job("mast", out)], [1, 2, 3, 4], out)
    with pytest.raises(KeyboardInterrupt):
        run.run()
    assert run.scanned == 2
    assert sorted(p.name for p in out.glob("*.pcd")) == ["fake_mast_000001.pcd",
                                                          "fake_mast_000002.pcd"]
    assert all(s.points > 0 for s in run.outputs)

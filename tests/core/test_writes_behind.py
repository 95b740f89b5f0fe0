"""The cloud writer's background writes: in order, at most WRITES_BEHIND waiting, a
failure raised at a later write or at flush with nothing left running behind it."""

import threading
import time

import pytest

from rls_addon.core.errors import OutputError
from rls_addon.core.output.io import writer as wmod
from rls_addon.core.output.io.writer import WRITES_BEHIND, CloudWriter


def test_writes_behind_keep_their_order_and_their_bound(monkeypatch):
    done, gate, most = [], threading.Event(), [0]
    writer = CloudWriter("s", background=True)

    def slow_write(path, sensor, output, points, info):
        gate.wait(5)
        done.append(info)

    monkeypatch.setattr(writer, "_write", slow_write)
    monkeypatch.setattr(writer, "path", lambda sensor, output, frame: f"{frame}.pcd")
    for frame in range(WRITES_BEHIND + 3):
        if frame == WRITES_BEHIND:
            threading.Timer(0.2, gate.set).start()  # the writer thread gets going
        writer.write("lidar", None, frame, None, frame)
        most[0] = max(most[0], len(writer._pending))
    writer.flush()
    assert done == list(range(WRITES_BEHIND + 3)) and most[0] <= WRITES_BEHIND
    assert not writer._pending


def test_a_failed_write_is_raised_later_and_stops_the_rest(monkeypatch):
    writer = CloudWriter("s", background=True)
    ran = []

    def write(path, sensor, output, points, info):
        ran.append(info)
        time.sleep(0.01)
        if info == 2:
            raise OutputError("disk full while writing 2.pcd")

    monkeypatch.setattr(writer, "_write", write)
    monkeypatch.setattr(writer, "path", lambda sensor, output, frame: f"{frame}.pcd")
    with pytest.raises(OutputError, match="2.pcd"):
        for frame in range(20):
            writer.write("lidar", None, frame, None, frame)
        writer.flush()
    assert not writer._pending  # nothing left running behind the error
    assert ran[:3] == [0, 1, 2] and len(ran) <= 3 + WRITES_BEHIND
    assert wmod.WRITES_BEHIND >= 2


def test_a_kitti_dataset_written_behind_the_scan_is_the_one_written_in_place(tmp_path,
                                                                             monkeypatch):
    """``rls dataset --layout kitti`` writes each frame behind the scan: the same files,
    byte for byte, as writing in place; the meta (a frame's last file) of every frame
    there once the writer is flushed; a failed frame raised at a later write."""
    import hashlib

    import numpy as np

    from rls_addon.core.output.datasets.kitti import KittiWriter
    from tests.core.evaluate.builders import info, object_boxes, points

    pose = np.eye(4)
    pose[2, 3] = 2.0
    digests = []
    for background in (False, True):
        root = tmp_path / str(background)
        writer = KittiWriter(root, "scene", background=background)
        for f in range(1, 9):
            writer.write("lidar", None, f, points(), info(pose, object_boxes(pose, (f, 0.0, 0.0))))
        writer.flush()
        assert len(list((root / "lidar" / "meta").glob("*.json"))) == 8
        digests.append({p.relative_to(root): hashlib.sha256(p.read_bytes()).hexdigest()
                        for p in sorted(root.rglob("*")) if p.is_file()})
    assert digests[0] == digests[1] and len(digests[0]) == 24
    writer = KittiWriter(tmp_path / "failing", "scene", background=True)
    real = writer._write

    def failing(sensor, output, frame, pts, inf):
        if frame == 2:
            raise OutputError("disk full while writing 000002.npy")
        return real(sensor, output, frame, pts, inf)

    monkeypatch.setattr(writer, "_write", failing)
    with pytest.raises(OutputError, match="000002"):
        for f in range(1, 20):
            writer.write("lidar", None, f, points(), info(pose, object_boxes(pose, (f, 0, 0))))
        writer.flush()
    assert not writer._behind.pending


def test_a_stop_while_waiting_for_the_last_write_leaves_no_write_running():
    """Ctrl-C (or the command line's SIGTERM handler) raises in the main thread while it
    waits for the last write behind (a run's flush as it winds down): the stop is
    raised, but only once that write has ended, so a run never ends (and Python never
    shuts down) with a write under way."""
    import os
    import signal

    from rls_addon.core.output.io.behind import WritesBehind

    behind, gate, done = WritesBehind(), threading.Event(), []

    def write(n):
        gate.wait(10)
        time.sleep(0.05)
        done.append(n)

    behind.run(write, 0)
    threading.Timer(0.2, os.kill, (os.getpid(), signal.SIGINT)).start()
    threading.Timer(0.6, gate.set).start()  # the write ends after the stop
    with pytest.raises(KeyboardInterrupt):
        behind.flush()
    assert done == [0] and not behind.pending  # the write waited on had ended

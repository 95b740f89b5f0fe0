"""A source that gives the same read again (an unedited file in which nothing but the
sensors can change: ``BlenderScene`` keeps its read) has its instances cleared of
non-finite triangles, its object table and its static key worked out once by the
session; every frame scans as it does from a fresh read each time, a NaN corner's
warning included."""

import numpy as np

from rls_addon.core.casting import NumpyCaster
from rls_addon.core.scan import session as session_module
from rls_addon.core.scan.session import ScanSession
from rls_addon.core.scan.settings import ScanSettings

from .fakes import small_preset, street

PRESET = small_preset()


class KeptRead:
    """``street()`` whose read is made once and given back (its car standing still, one
    wall corner NaN)."""

    def __init__(self):
        self.scene = street()
        self._read = None

    def __getattr__(self, name):
        return getattr(self.scene, name)

    def read(self, centre, max_range, exclude):
        if self._read is None:
            self._read = self.scene.read(centre, max_range, exclude)
            wall = next(i for i in self._read.instances if i.key == "wall")
            wall.vertices = wall.vertices.copy()
            wall.vertices[0, 0] = np.nan
        return self._read


def test_a_kept_read_is_cleared_once_and_scans_as_fresh_reads(monkeypatch):
    counted = {"without_nonfinite": 0}
    real = session_module.without_nonfinite

    def counting(instances, skipped):
        counted["without_nonfinite"] += 1
        return real(instances, skipped)

    monkeypatch.setattr(session_module, "without_nonfinite", counting)
    settings = ScanSettings(seed=5)
    kept, fresh_session = ScanSession(NumpyCaster), ScanSession(NumpyCaster)
    source = KeptRead()
    for frame in (1, 2, 3):
        source.set_frame(frame)
        got, info = kept.scan(source, "pole", PRESET, settings, frame)
        fresh_source = KeptRead()  # a read of its own: nothing kept
        fresh_source.set_frame(frame)
        want, want_info = fresh_session.scan(fresh_source, "pole", PRESET, settings, frame)
        assert got.points.tobytes() == want.points.tobytes()
        assert got.warnings == want.warnings and "wall" in got.warnings[0]
        assert info["labels"] == want_info["labels"]
    assert counted["without_nonfinite"] == 1 + 3  # the kept read once, each fresh one once

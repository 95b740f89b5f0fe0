"""Triangles with a NaN or infinite vertex coordinate (a broken import, a driver that
divided by zero) are skipped with one warning naming their objects; numpy prints
nothing, and the rest of the scene and of those objects is scanned."""

import warnings

import numpy as np
import pytest

from rls_addon.core.casting import NumpyCaster
from rls_addon.core.scan.session import ScanSession
from rls_addon.core.scan.settings import ScanSettings
from rls_addon.core.scene.geometry import clean_for_casting

from .fakes import small_preset, street
from .scenes import box_geometry, merge

PRESET = small_preset()


def broken(scene, bad):
    """``scene`` whose objects ``bad`` ({name: (vertex, value)}) have one vertex
    coordinate set to ``value``."""
    read = scene._instance

    def instance(name, seconds):
        inst = read(name, seconds)
        if name in bad:
            k, value = bad[name]
            inst.vertices = inst.vertices.copy()
            inst.vertices[k, 0] = value
        return inst

    scene._instance = instance
    return scene


def test_clean_for_casting_skips_non_finite_triangles_naming_their_objects():
    a = box_geometry((0, 0, 0), (1, 1, 1), name="good")
    b = box_geometry((3, 0, 0), (4, 1, 1), name="nan box")
    c = box_geometry((6, 0, 0), (7, 1, 1), name="inf box")
    g = merge(a, b, c)
    g.vertices[8, 1] = np.nan    # a corner of 'nan box'
    g.vertices[16, 2] = np.inf   # a corner of 'inf box'
    per_corner = int(np.sum(np.any(g.triangles == 8, axis=1)))
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # no RuntimeWarning from numpy
        local, tris, kept, said = clean_for_casting(g, np.zeros(3), 100.0)
    assert said == [f"skipped {2 * per_corner} triangle(s) with NaN or infinite vertex "
                    f"coordinates: 'inf box' ({per_corner}), 'nan box' ({per_corner}); fix "
                    "those objects' vertices or transforms to scan them"]
    assert len(kept) == 36 - 2 * per_corner
    assert np.isfinite(local[tris]).all()


@pytest.mark.parametrize("speed", [0.0, 5.0], ids=["still", "moving"])
def test_a_scan_skips_them_with_one_warning_and_scans_the_rest(speed):
    scene = broken(street(car_speed=speed), {"car": (0, np.nan), "wall": (3, np.inf)})
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        result, info = ScanSession(NumpyCaster).scan(scene, "pole", PRESET,
                                                     ScanSettings(noise=False), 1)
    said = [w for w in result.warnings if "NaN or infinite" in w]
    assert said == ["skipped 9 triangle(s) with NaN or infinite vertex coordinates: 'car' "
                    "(5), 'wall' (4); fix those objects' vertices or transforms to scan them"]
    assert not any("degenerate" in w for w in result.warnings)
    assert info["warnings"] == result.warnings
    # the rest of the car (still or moving) is scanned
    car = [int(k) for k, v in info["labels"].items() if v["object"] == "car"]
    assert np.count_nonzero(result.points["instance"] == car[0]) > 10
    assert np.isfinite(result.points["x"]).all()


def test_an_object_whose_matrix_is_not_finite_is_skipped_whole_with_the_warning():
    scene = street()
    scene.motion["wall"] = lambda s: np.diag([np.nan, 1.0, 1.0, 1.0])
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        result, info = ScanSession(NumpyCaster).scan(scene, "pole", PRESET, ScanSettings(), 1)
    assert [w for w in result.warnings if "NaN" in w] == [
        "skipped 12 triangle(s) with NaN or infinite vertex coordinates: 'wall' (12); fix "
        "those objects' vertices or transforms to scan them"]
    assert "wall" not in {v["object"] for v in info["labels"].values()}


def test_instances_are_cleared_by_their_sums_as_row_by_row():
    """``without_nonfinite`` clears an instance by the sum of its vertices and of its
    matrix (a NaN or an infinity never cancels out of a sum): the same instances as
    looking at every row, with finite coordinates whose sum overflows kept whole."""
    from rls_addon.core.scene.instances import Instance, without_nonfinite

    def inst(key, vertices, matrix=None):
        v = np.asarray(vertices, np.float64)
        return Instance(key, key, "", 1, v, np.array([[0, 1, 2], [1, 2, 3]]),
                        np.zeros(2, np.int32), np.eye(4) if matrix is None else matrix,
                        np.zeros(1, np.int32))

    quad = [[0, 0, 0], [1, 0, 0], [0, 1, 0], [1, 1, 0]]
    huge = [[1.7e308, 0, 0], [1.7e308, 0, 0], [1.7e308, 0, 0], [1, 1, 0]]  # sum overflows
    nan, inf_matrix = [row[:] for row in quad], np.eye(4)
    nan[3][2] = np.nan
    inf_matrix[0, 3] = np.inf
    given = [inst("a", quad), inst("huge", huge), inst("nan", nan), inst("inf", quad, inf_matrix),
             inst("empty", np.zeros((0, 3)))]
    skipped = {}
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # no RuntimeWarning from numpy
        got = without_nonfinite(given, skipped)
    assert [i.key for i in got] == ["a", "huge", "nan", "empty"]
    assert got[0] is given[0] and got[1] is given[1] and got[3] is given[4]
    assert got[2].triangles.tolist() == [[0, 1, 2]] and skipped == {"nan": 1, "inf": 2}

"""The benchmark street is modelled as a user's scene would be."""

import numpy as np

from bench.scene import street_geometry


def test_facades_and_windows_face_the_street():
    """Both rows of buildings show the street the front of their faces (a sensor on
    the road meets no back faces there, so it is not taken to be inside them)."""
    g = street_geometry(20_000)
    tv = g.vertices[g.triangles]
    n = np.cross(tv[:, 1] - tv[:, 0], tv[:, 2] - tv[:, 0])
    names = np.array([o.name.split(" ")[0] for o in g.objects])[g.tri_object]
    for kind in ("Facade", "Windows"):
        sel = names == kind
        y = tv[sel, :, 1].mean(axis=1)  # north row at y > 0, south row at y < 0
        assert sel.sum() > 100
        assert np.all(np.sign(n[sel, 1]) == -np.sign(y)), kind


def test_benchmark_modules_import():
    """make bench is not run by the tests: at least its modules must load."""
    import importlib

    for name in ("bench.run", "bench.report", "bench.machine", "bench.timing", "bench.backends",
                 "bench.devices", "bench.scaling", "bench.memory", "bench.tessellation",
                 "bench.blender_scan", "bench.engine_costs"):
        importlib.import_module(name)

"""Backends agree: BVHTree against the exact numpy reference on analytic scenes, and
Embree against BVHTree there and on the sample street scene (after the engine's exact
float64 refinement, identical hit/miss sets away from triangle edges)."""

import numpy as np
import pytest

from rls_addon.core import casting as backends
from rls_addon.core.casting import BVHCaster
from rls_addon.core.casting import embree as embree_caster
from rls_addon.core.casting import NumpyCaster
from tests import parity
from tests.core.external_tools import require_backend

pytestmark = pytest.mark.filterwarnings("ignore:invalid value encountered:RuntimeWarning")


@pytest.fixture
def embreex():
    require_backend(embree_caster, "embreex")


needs_embree = pytest.mark.usefixtures("embreex")


def rays():
    return np.concatenate([parity.random_directions(3000, seed=5),
                           parity.lidar_directions(columns=180)])


SCENES = {
    "plane": (lambda: parity.grid_plane(), (0.3, -0.2, 0.0), 60.0),
    "plane_far": (lambda: parity.grid_plane(offset=(1e5, 5e4, 10.0)), (1e5 + 0.3, 5e4, 10.0), 60.0),
    "box_interior": (lambda: parity.box(), (0.5, 0.25, 0.1), 100.0),
    "sphere_inside": (lambda: parity.uv_sphere(), (0.4, -0.7, 0.9), 50.0),
    "sphere_outside": (lambda: parity.uv_sphere(), (9.0, 1.0, 0.5), 50.0),
}


@pytest.mark.parametrize("name", sorted(SCENES))
def test_bvhtree_matches_numpy_reference(addon, name):
    make, origin, max_range = SCENES[name]
    parity.compare(make(), origin, rays(), max_range, NumpyCaster, BVHCaster)


@needs_embree
@pytest.mark.parametrize("name", sorted(SCENES))
def test_embree_matches_bvhtree(addon, name):
    make, origin, max_range = SCENES[name]
    parity.compare(make(), origin, rays(), max_range, BVHCaster, embree_caster.EmbreeCaster)


@needs_embree
def test_embree_matches_bvhtree_on_sample_street(scene):
    import bpy

    from rls_addon.blender.extract import extract_geometry
    from rls_addon.blender.sample_scene import build_street

    mount = build_street(scene)
    geom, _ = extract_geometry(bpy.context.evaluated_depsgraph_get())
    assert geom.triangle_count > 100
    d = np.concatenate([parity.random_directions(20000, seed=11),
                        parity.lidar_directions(channels=64, columns=900)])
    for origin in (mount, (0.0, 0.0, 1.8), (25.0, 3.0, 0.5)):
        r = parity.compare(geom, origin, d, 120.0, BVHCaster, embree_caster.EmbreeCaster)
        assert r["hits_a"] > len(d) // 4


def test_caster_factory_names_and_fallback_notice(monkeypatch):
    assert backends.caster_factory("bvhtree") == (BVHCaster, None)
    with pytest.raises(ValueError, match="unknown ray-casting backend"):
        backends.caster_factory("optix")
    if embree_caster.available():
        assert backends.caster_factory("embree") == (embree_caster.EmbreeCaster, None)
        assert backends.caster_factory("auto") == (embree_caster.EmbreeCaster, None)
        assert "embree" in backends.backend_names()
    monkeypatch.setattr(embree_caster, "available", lambda: False)
    monkeypatch.setattr(embree_caster, "unavailable_reason",
                        lambda: "ModuleNotFoundError: No module named 'embreex'")
    # Nor pyemblite (the macOS zips' Embree) or Open3D: BVHTree
    # (tests/core/test_backends_without_embreex.py).
    monkeypatch.setattr(backends.emblite, "available", lambda: False)
    monkeypatch.setattr(backends.open3d_caster, "available", lambda: False)
    factory, notice = backends.caster_factory("embree")
    assert factory is BVHCaster
    assert "Embree is not available" in notice and "BVHTree" in notice and "embreex" in notice
    assert backends.caster_factory("auto") == (BVHCaster, None)
    assert backends.backend_names() == ("bvhtree",)


@needs_embree
def test_scan_with_embree_equals_scan_with_bvhtree(scene):
    """The whole frame (effects included) is the same whichever backend cast it."""

    from rls_addon.blender.sample_scene import build_street
    from rls_addon.blender.scan import scan_lidar
    from tests.blender.conftest import add_lidar

    mount = build_street(scene)
    lidar = add_lidar(location=mount)
    a, info_a = scan_lidar(lidar, backend="bvhtree")
    b, info_b = scan_lidar(lidar, backend="embree")
    assert info_b["backend"] == "embree" and info_a["backend"] == "bvhtree"
    pa, pb = a.points, b.points
    # Rays grazing an edge may differ; everything else is identical.
    assert abs(len(pa) - len(pb)) <= max(3, len(pa) // 2000)
    key = lambda p: np.round(np.stack([p["x"], p["y"], p["z"]], 1), 3)  # noqa: E731
    sa = {tuple(r) for r in key(pa)}
    sb = {tuple(r) for r in key(pb)}
    assert len(sa ^ sb) <= max(6, len(pa) // 1000)

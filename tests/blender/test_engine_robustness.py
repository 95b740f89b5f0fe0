"""Where ray casting usually breaks: curved tessellation, grazing rays, rays from
inside geometry, degenerate triangles, mirrored objects, curves and text."""

import math

import bmesh
import bpy
import numpy as np
import pytest

from .conftest import add_lidar, ground, mesh_object, scan, xyz


def bm_object(name, build, location=(0, 0, 0)):
    mesh = bpy.data.meshes.new(name)
    bm = bmesh.new()
    build(bm)
    bm.to_mesh(mesh)
    bm.free()
    obj = bpy.data.objects.new(name, mesh)
    obj.location = location
    bpy.context.scene.collection.objects.link(obj)
    return obj


def test_box_interior_ranges_exact(scene):
    bm_object("Room", lambda bm: bmesh.ops.create_cube(bm, size=1.0),
              location=(0, 0, 0)).scale = (20.0, 12.0, 6.0)
    lidar = add_lidar(location=(1.3, -0.7, 0.4))
    result, info = scan(lidar)
    p = result.points
    assert len(p) == result.rays  # a closed room: every ray returns
    d = xyz(p) / p["range"][:, None]
    o = np.array([1.3, -0.7, 0.4])
    lo, hi = np.array([-10, -6, -3]), np.array([10, 6, 3])
    with np.errstate(divide="ignore", invalid="ignore"):
        t = np.where(d > 0, (hi - o) / d, np.where(d < 0, (lo - o) / d, np.inf))
    assert np.abs(p["range"] - t.min(axis=1)).max() <= 1e-4
    assert any("inside 'Room'" in w for w in info["warnings"])  # and it says so


@pytest.mark.parametrize("segments", [16, 32, 64, 128])
def test_sphere_range_error_within_chord_sagitta(scene, segments):
    r = 10.0
    rings = segments // 2
    bm_object("Sphere", lambda bm: bmesh.ops.create_uvsphere(
        bm, u_segments=segments, v_segments=rings, radius=r))
    lidar = add_lidar(location=(0, 0, 0))
    p = scan(lidar)[0].points
    assert len(p) > 1000
    # Faces are flat polygons inscribed in the sphere: a point on one is at most the
    # sagitta of the face's angular circumradius closer to the centre than r.
    half_diag = 0.5 * math.hypot(2 * math.pi / segments, math.pi / rings)
    sagitta = r * (1 - math.cos(half_diag))
    err = r - p["range"]
    assert err.min() >= -1e-4 and err.max() <= sagitta + 1e-4


@pytest.mark.parametrize("segments", [12, 48])
def test_cylinder_range_error_within_chord_sagitta(scene, segments):
    r = 5.0
    bm_object("Pipe", lambda bm: bmesh.ops.create_cone(
        bm, cap_ends=True, segments=segments, radius1=r, radius2=r, depth=40.0))
    lidar = add_lidar(location=(0, 0, 0))
    p = scan(lidar)[0].points
    horizontal = np.hypot(p["x"], p["y"])
    sagitta = r * (1 - math.cos(math.pi / segments))
    assert horizontal.max() <= r + 1e-4
    assert horizontal.min() >= r - sagitta - 1e-4
    assert horizontal.min() < r - 0.5 * sagitta  # the faceting is really seen


def test_grazing_rays_on_a_plane_are_exact(scene):
    ground(size=2000.0)
    lidar = add_lidar(location=(0, 0, 0.05))
    lidar.rls_lidar.use_max_range = True
    lidar.rls_lidar.max_range = 100.0
    p = scan(lidar)[0].points
    d = xyz(p) / p["range"][:, None]
    elev = np.degrees(np.arcsin(-d[:, 2]))
    grazing = elev < 1.0  # down to the lowest rays that reach the plane within 100 m
    assert grazing.sum() > 100
    assert np.abs(p["range"] - 0.05 / -d[:, 2]).max() <= 1e-4
    assert np.abs(p["z"] + 0.05).max() <= 1e-6


def test_ray_exactly_in_the_plane_and_sensor_on_the_surface(scene):
    ground()
    lidar = add_lidar(location=(0, 0, 0))  # on the plane: horizontal rays run along it
    result, info = scan(lidar)
    p = result.points
    assert np.isfinite(p["range"]).all()
    # Rays below the horizon hit at (nearly) zero range: the blind zone removes them.
    assert (p["range"] >= 0.5).all()  # generic_uniform32's minimum range


def test_degenerate_triangles_are_skipped_with_a_warning(scene):
    ground()
    mesh_object("Sliver", [(3, 0, 0), (4, 0, 0), (5, 0, 0), (3, 0, 1), (4, 0, 1)],
                [(0, 1, 2), (0, 1, 4, 3)])
    lidar = add_lidar(location=(0, 0, 1.5))
    result, info = scan(lidar)
    assert any("degenerate" in w for w in info["warnings"])
    assert len(result.points) > 0


def test_negative_scale_object_is_scanned_mirrored_and_exact(scene):
    wall = mesh_object("Wall", [(5, -3, 0), (5, 3, 0), (5, 3, 3), (5, -3, 3)], [(0, 1, 2, 3)])
    wall.scale = (-1.0, 1.0, 1.0)  # mirrored to x = -5
    lidar = add_lidar(location=(0, 0, 1.5))
    p = scan(lidar)[0].points
    assert len(p) > 0
    assert np.abs(p["x"] + 5.0).max() <= 1e-4


def test_curves_and_text_are_scanned_as_meshes(scene):
    curve = bpy.data.curves.new("Rail", "CURVE")
    curve.dimensions = "3D"
    curve.bevel_depth = 0.3
    spline = curve.splines.new("POLY")
    spline.points.add(1)
    spline.points[0].co = (6, -5, 1.5, 1)
    spline.points[1].co = (6, 5, 1.5, 1)
    rail = bpy.data.objects.new("Rail", curve)
    bpy.context.scene.collection.objects.link(rail)
    text = bpy.data.curves.new("Sign", "FONT")
    text.body = "STOP"
    text.size = 2.0
    text.extrude = 0.1
    sign = bpy.data.objects.new("Sign", text)
    sign.location = (-6, 2, 0.5)
    sign.rotation_euler = (math.pi / 2, 0, math.pi / 2)
    bpy.context.scene.collection.objects.link(sign)
    lidar = add_lidar(location=(0, 0, 1.5))
    result, info = scan(lidar)
    names = {v["object"] for v in info["labels"].values()}
    assert names == {"Rail", "Sign"}
    inst = {v["object"]: int(k) for k, v in info["labels"].items()}
    hit = set(np.unique(result.points["instance"]))
    assert inst["Rail"] in hit and inst["Sign"] in hit


def test_nothing_in_range_warns(scene):
    mesh_object("Far", [(500, -5, 0), (500, 5, 0), (500, 5, 5), (500, -5, 5)], [(0, 1, 2, 3)])
    lidar = add_lidar()
    result, info = scan(lidar)
    assert len(result.points) == 0
    assert any("no geometry" in w for w in info["warnings"])


def test_nan_and_infinite_vertices_are_skipped_with_one_warning_naming_them(scene):
    import warnings

    ground()
    broken = mesh_object("Broken", [(5, -3, 0), (5, 3, 0), (5, 3, 3), (5, -3, 3), (5, 0, 5)],
                         [(0, 1, 2, 3), (2, 4, 3)])
    far = mesh_object("Far", [(-5, -3, 0), (-5, 3, 0), (-5, 3, 3), (-5, -3, 3)], [(0, 1, 2, 3)])
    for obj, vertex, value in ((broken, 4, np.nan), (far, 0, np.inf)):
        # as an importer writes them (a vertex's co clamps infinity to the float maximum)
        co = np.zeros(3 * len(obj.data.vertices), np.float32)
        obj.data.attributes["position"].data.foreach_get("vector", co)
        co[3 * vertex] = value
        obj.data.attributes["position"].data.foreach_set("vector", co)
        obj.data.update()
    lidar = add_lidar(location=(0, 0, 1.5))
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # numpy prints nothing
        result, info = scan(lidar)
    said = [w for w in info["warnings"] if "NaN" in w or "degenerate" in w]
    assert said == ["skipped 3 triangle(s) with NaN or infinite vertex coordinates: "
                    "'Broken' (1), 'Far' (2); fix those objects' vertices or transforms to "
                    "scan them"]
    hit = {info["labels"][str(i)]["object"] for i in np.unique(result.points["instance"])}
    assert hit == {"Ground", "Broken"}  # the rest of 'Broken' is scanned

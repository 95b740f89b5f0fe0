"""Motion distortion and ghosting through the Blender layer (BVHTree unless a test names
its backend; animation)."""

import bpy
import pytest
import numpy as np

from .conftest import add_lidar, mesh_object, scan

V = 20.0  # m/s
FPS = 25


def box(name, lo, hi):
    (x0, y0, z0), (x1, y1, z1) = lo, hi
    verts = [(x0, y0, z0), (x1, y0, z0), (x1, y1, z0), (x0, y1, z0),
             (x0, y0, z1), (x1, y0, z1), (x1, y1, z1), (x0, y1, z1)]
    faces = [(0, 3, 2, 1), (4, 5, 6, 7), (0, 1, 5, 4), (1, 2, 6, 5), (2, 3, 7, 6), (3, 0, 4, 7)]
    return mesh_object(name, verts, faces)


def linear_keys(idblock, path, frames_values):
    """Keyframes with linear interpolation (constant velocity between keys)."""
    from bpy_extras import anim_utils

    for f, value in frames_values:
        setattr(idblock, path, value)
        idblock.keyframe_insert(path, frame=f)
    ad = idblock.id_data.animation_data  # a shape key animates its Key datablock
    bag = anim_utils.action_get_channelbag_for_slot(ad.action, ad.action_slot)
    for fc in bag.fcurves:
        for kp in fc.keyframe_points:
            kp.interpolation = "LINEAR"


def box_sdf(p, centre, half):
    q = np.abs(p - centre) - half
    return np.linalg.norm(np.maximum(q, 0), axis=1) + np.minimum(q.max(axis=1), 0)


def moving_box_setup(scene):
    scene.render.fps, scene.render.fps_base = FPS, 1.0
    car = box("Car", (-1, -2, -1), (1, 2, 1))
    start = np.array([10.0, -6.0, 0.0])
    step = V / FPS  # metres per frame
    linear_keys(car, "location", [(1, tuple(start)), (11, tuple(start + [0, 10 * step, 0]))])
    lidar = add_lidar(location=(0, 0, 0))
    lidar.rls_lidar.frame_space = "world"
    return lidar, start


def points_xyz(p):
    return np.stack([p["x"], p["y"], p["z"]], 1)


def test_rigid_motion_exact_every_point_on_the_box_at_its_time(scene):
    lidar, start = moving_box_setup(scene)
    result, info = scan(lidar, frame=1)
    p = result.points
    assert info["motion"]["rigid"] == ["Car"] and not info["motion"]["deforming"]
    assert len(p) > 50
    centre = start + np.outer(p["time"], [0, V, 0])
    err = np.abs(box_sdf(points_xyz(p), centre, np.array([1, 2, 1])))
    assert err.max() <= 1e-3


def test_substeps_and_snapshot_modes_through_blender(scene):
    from rls_addon.blender.scan import scan_lidar
    from rls_addon.blender.sensor import read_settings

    lidar, start = moving_box_setup(scene)
    base = read_settings(lidar)
    for mode, n in (("substeps", 4), ("snapshot", 0)):
        settings = base.override(motion=mode, substeps=n)
        res, info = scan_lidar(lidar, 1, backend="bvhtree", settings=settings)
        p = res.points
        centre = start + np.outer(p["time"], [0, V, 0])
        err = np.abs(box_sdf(points_xyz(p), centre, np.array([1, 2, 1])))
        bound = V * 0.1 / (2 * n) if n else V * 0.1
        assert err.max() <= bound + 1e-4


def test_moving_sensor_in_static_room_follows_its_pose(scene):
    scene.render.fps, scene.render.fps_base = FPS, 1.0
    room = box("Room", (-10, -6, -1), (10, 6, 5))
    lidar = add_lidar(location=(-2, 0.5, 1.5))
    lidar.rls_lidar.frame_space = "world"
    # 10 m/s along +X: 0.4 m per frame.
    linear_keys(lidar, "location", [(1, (-2.0, 0.5, 1.5)), (11, (2.0, 0.5, 1.5))])
    result, info = scan(lidar, frame=1)
    p = result.points
    assert info["motion"]["sensor_moves"] and not info["motion"]["rigid"]
    t = p["time"]
    origin = np.stack([-2 + 10 * t, np.full_like(t, 0.5), np.full_like(t, 1.5)], 1)
    xyz = points_xyz(p)
    d = (xyz - origin) / p["range"][:, None]
    assert np.abs(np.linalg.norm(d, axis=1) - 1).max() <= 1e-6  # on the ray from its origin
    lo, hi = np.array([-10, -6, -1]), np.array([10, 6, 5])
    with np.errstate(divide="ignore", invalid="ignore"):
        tt = np.where(d > 0, (hi - origin) / d, np.where(d < 0, (lo - origin) / d, np.inf))
    assert np.abs(p["range"] - tt.min(axis=1)).max() <= 1e-4
    assert room.name == "Room"


def test_deforming_object_is_substepped_adaptively(scene):
    scene.render.fps, scene.render.fps_base = FPS, 1.0
    wall = mesh_object("Wall", [(6, -4, -2), (6, 4, -2), (6, 4, 2), (6, -4, 2)], [(0, 1, 2, 3)])
    wall.shape_key_add(name="Basis")
    key = wall.shape_key_add(name="Away")
    for i, v in enumerate(key.data):
        v.co.x += 4.0  # the wall moves 4 m in x at full weight
    linear_keys(key, "value", [(1, 0.0), (11, 1.0)])  # 10 frames = 0.4 s for 4 m: 10 m/s
    lidar = add_lidar(location=(0, 0, 0))
    lidar.rls_lidar.frame_space = "world"
    result, info = scan(lidar, frame=1)
    p = result.points
    n = info["motion"]["substeps"]["Wall"]
    assert info["motion"]["deforming"] == ["Wall"] and n >= 8
    expected_x = 6 + 10.0 * p["time"]
    assert np.abs(p["x"] - expected_x).max() <= 10.0 * 0.1 / (2 * n) + 1e-4


def test_animated_but_still_objects_cost_nothing(scene):
    scene.render.fps, scene.render.fps_base = FPS, 1.0
    post = box("Post", (4, -0.5, 0), (5, 0.5, 3))
    linear_keys(post, "location", [(1, (0.0, 0.0, 0.0)), (20, (0.0, 0.0, 0.0))])
    lidar = add_lidar(location=(0, 0, 1))
    _, info = scan(lidar, frame=1)
    assert info["motion"]["rigid"] == [] and info["motion"]["deforming"] == []


def test_glossy_principled_material_makes_ghosts(scene):
    wall = box("Glass", (5.0, -20, -5), (5.2, 20, 5))
    mat = bpy.data.materials.new("Glass")
    bsdf = next(n for n in mat.node_tree.nodes if n.type == "BSDF_PRINCIPLED")
    bsdf.inputs["Metallic"].default_value = 1.0
    bsdf.inputs["Roughness"].default_value = 0.02
    wall.data.materials.append(mat)
    box("Car", (-3.0, -1, -1), (-2.0, 1, 1))
    lidar = add_lidar(location=(0, 0, 0))
    lidar.rls_lidar.frame_space = "world"
    result, info = scan(lidar)
    g = result.points[result.points["ghost"] == 1]
    assert info["ghosts"] == len(g) > 20
    image = points_xyz(g)
    image[:, 0] = 10.0 - image[:, 0]
    assert np.abs(box_sdf(image, np.array([-2.5, 0, 0]), np.array([0.5, 1, 1]))).max() <= 1e-4


@pytest.mark.parametrize("backend", ["bvhtree", "embree"])
def test_one_session_over_frames_keeps_every_point_on_the_moving_box(scene, backend):
    """A session reuses the car's structure over frames with each sweep's own track
    (with Embree: the car traced as an instance), and the street's cast of the still
    lidar: every frame gives what a fresh session gives, and every car point lies on
    the car."""
    from rls_addon.blender.scan import scan_lidar
    from rls_addon.blender.source import BlenderScene
    from rls_addon.core.world.bodies import PreparedScene
    from rls_addon.core.casting import caster_factory
    from rls_addon.core.scan.session import ScanSession

    lidar, start = moving_box_setup(scene)
    box("Ground", (-30, -30, -3), (30, 30, -2))
    factory, notice = caster_factory(backend)
    assert notice is None
    session, source = ScanSession(factory), BlenderScene(scene)
    static_casts = []
    cast = PreparedScene._start

    def counting(self, origins, directions, max_range, watertight, order):
        if watertight:  # the street's casts (reflected beams are cast without re-check)
            static_casts.append(self)
        return cast(self, origins, directions, max_range, watertight, order)

    PreparedScene._start = counting
    step = V / FPS
    try:
        for frame in (1, 3, 6):
            result, info = scan_lidar(lidar, frame, session=session, source=source)
            fresh, _ = scan_lidar(lidar, frame, session=ScanSession(factory))
            p = result.points
            assert info["motion"]["rigid"] == ["Car"]
            assert result.stats["static_cast_reused"] == (frame != 1)
            assert len(p) == len(fresh.points)
            assert np.abs(p["range"] - fresh.points["range"]).max() <= 1e-9
            check_car(p, start, frame, step)
    finally:
        PreparedScene._start = cast
    # The lidar stands still: the session cast its street once, in the first frame, and
    # reused that cast in the others (see PreparedScene.cast)
    street = list(session._prepared.values())
    assert len(street) == 1
    assert sum(1 for s in static_casts if s is street[0]) == 1


def check_car(p, start, frame, step):
    """Every car point lies on the box where it was at the point's own time."""
    car = p[p["z"] > -1.9]  # the ground's top is at z = -2
    assert len(car) > 50
    centre = start + [0, (frame - 1) * step, 0] + np.outer(car["time"], [0, V, 0])
    err = np.abs(box_sdf(points_xyz(car), centre, np.array([1, 2, 1])))
    assert err.max() <= 1e-3, (frame, err.max())


@pytest.mark.parametrize("backend", ["bvhtree", "embree"])
def test_a_driving_lidar_shares_one_built_scene_over_frames(scene, backend):
    """Once the lidar has moved, its static scene is prepared wider and kept while the
    lidar stays inside it: frames share one structure, and give what a fresh session
    gives; far enough on, the scene is prepared anew."""
    from rls_addon.blender.scan import scan_lidar
    from rls_addon.blender.source import BlenderScene
    from rls_addon.core.scan import session as scan_module
    from rls_addon.core.casting import caster_factory
    from rls_addon.core.scan.session import ScanSession

    scene.render.fps, scene.render.fps_base = FPS, 1.0
    box("Street", (-60, -8, -1), (60, 8, 6))
    box("Kiosk", (3, 2, -1), (5, 4, 1))
    lidar = add_lidar(location=(-2, 0.5, 1.5))
    lidar.rls_lidar.frame_space = "world"
    lidar.rls_lidar.use_max_range, lidar.rls_lidar.max_range = True, 20.0
    # 10 m/s along +X: 0.4 m per frame
    linear_keys(lidar, "location", [(1, (-2.0, 0.5, 1.5)), (101, (38.0, 0.5, 1.5))])
    factory = caster_factory(backend)[0]
    session, source = ScanSession(factory), BlenderScene(scene)
    for frame in (1, 2, 3, 4, 5, 6):
        result, info = scan_lidar(lidar, frame, session=session, source=source)
        fresh, _ = scan_lidar(lidar, frame, session=ScanSession(factory))
        assert info["motion"]["sensor_moves"]
        assert len(result.points) == len(fresh.points) > 1000
        assert np.abs(result.points["range"] - fresh.points["range"]).max() <= 1e-6
        assert np.abs(points_xyz(result.points) - points_xyz(fresh.points)).max() <= 1e-6
    # an animated lidar's scene is prepared around the grid point nearest to it (every
    # 5 m for its 20 m range): frames 1-6 (x from -2 to 0) share the one at x = 0
    assert session.builds == 1
    far = 1 + int((20.0 * scan_module.DRIVING_SLACK) / 0.4) + 2  # x = 3.6: the next one
    scan_lidar(lidar, far, session=session, source=source)
    assert session.builds == 2


def test_a_driving_lidars_sensor_frame_cloud_maps_onto_the_scene_with_its_sidecar(scene, tmp_path):
    """At 20 m/s the sensor moves 2 m in a sweep: the sidecar's pose knots map every
    sensor-frame point through the pose at its own time (as ``rls metrics`` does), onto
    the room's walls within 1 cm; the sweep-start pose alone is metres off."""
    from rls_addon.blender.batch import make_run
    from rls_addon.commands.metrics import world_points
    from rls_addon.core.output.io import read_cloud, read_sidecar

    scene.render.fps, scene.render.fps_base = FPS, 1.0
    box("Room", (-30, -6, -1), (30, 6, 5))
    lidar = add_lidar(location=(-10.0, 0.5, 1.5))
    lidar.rls_lidar.output_dir = str(tmp_path)
    linear_keys(lidar, "location", [(1, (-10.0, 0.5, 1.5)), (26, (10.0, 0.5, 1.5))])  # 20 m/s
    run = make_run(bpy.context, [lidar], [3], preview=False).run()
    cloud = run.paths[0]
    side = read_sidecar(cloud)
    assert side["sensor_moves"] and side["frame_space"] == "sensor"
    start, end = np.array(side["sensor_pose_start"]), np.array(side["sensor_pose_end"])
    assert end[0, 3] - start[0, 3] == pytest.approx(2.0, abs=1e-3)
    world = world_points(cloud)
    xyz = np.stack([world["x"], world["y"], world["z"]], 1)
    err = np.abs(box_sdf(xyz, np.array([0.0, 0.0, 2.0]), np.array([30.0, 6.0, 3.0])))
    assert len(xyz) > 1000 and err.max() <= 0.01
    raw = read_cloud(cloud)
    naive = np.stack([raw["x"], raw["y"], raw["z"]], 1) @ start[:3, :3].T + start[:3, 3]
    assert np.abs(box_sdf(naive, np.array([0.0, 0.0, 2.0]), np.array([30.0, 6.0, 3.0]))).max() > 0.5

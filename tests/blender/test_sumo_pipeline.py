"""The SUMO scene pipeline without surprises (issue #37): what ``rls traffic import``
makes, checked in Blender on small hand-written FCD files (no SUMO run needed)."""

import numpy as np
import pytest

from .conftest import add_lidar, bpy, ground

from rls_addon.blender.traffic import PROFILES, import_traffic, profile_mesh  # noqa: E402
from rls_addon.core.labels import label_id  # noqa: E402
from rls_addon.core.traffic.fcd import load  # noqa: E402


def signed_volume(mesh):
    """The mesh's signed volume (divergence theorem over its polygons, fanned into
    triangles): positive when every face's normal points out of the solid."""
    co = np.array([v.co[:] for v in mesh.vertices], dtype=np.float64)
    vol = 0.0
    for poly in mesh.polygons:
        idx = list(poly.vertices)
        a = co[idx[0]]
        for i in range(1, len(idx) - 1):
            vol += np.dot(a, np.cross(co[idx[i]], co[idx[i + 1]])) / 6.0
    return vol


@pytest.mark.parametrize("shape", sorted(PROFILES))
def test_every_traffic_mesh_has_outward_normals(scene, shape):
    """Positive signed volume, equal to the profile's area x the width (the profile is
    extruded across the width); every face's normal points away from the box's
    inside along the axis it faces."""
    size = (4.0, 2.0, 1.5)
    mesh = profile_mesh(f"m {shape}", shape, size)
    prof = np.array(PROFILES[shape]) * (size[0], size[2])
    x, z = prof[:, 0], prof[:, 1]
    area = 0.5 * abs(np.dot(x, np.roll(z, -1)) - np.dot(z, np.roll(x, -1)))
    assert signed_volume(mesh) == pytest.approx(area * size[1], rel=1e-6)
    for poly in mesh.polygons:
        n = np.array(poly.normal[:])
        c = np.array(poly.center[:])
        if abs(n[1]) > 0.99:  # the two side faces
            assert np.sign(n[1]) == np.sign(c[1])
    mesh.validate()


FCD_ONE_BUS = """<?xml version="1.0" encoding="UTF-8"?>
<fcd-export>
    <timestep time="0.00">
        <vehicle id="bus0" x="16.00" y="0.00" angle="90.00" type="DEFAULT_BUS" speed="0.00" pos="16.00" lane="a_0" slope="0.00"/>
    </timestep>
    <timestep time="0.10">
        <vehicle id="bus0" x="16.00" y="0.00" angle="90.00" type="DEFAULT_BUS" speed="0.00" pos="16.00" lane="a_0" slope="0.00"/>
    </timestep>
</fcd-export>
"""
VTYPES_BUS = """<additional>
    <vType id="DEFAULT_BUS" vClass="bus"/>
</additional>
"""


def test_a_lidar_beside_an_imported_bus_is_not_inside_it(scene, tmp_path):
    """A LiDAR 6 m from a standing bus sees its outside: no 'the sensor is inside'
    warning (with inward faces, every hit on the bus was on a back face)."""
    from rls_addon.blender.sensor import read_settings, sensor_job
    from rls_addon.blender.source import BlenderScene
    from rls_addon.core.casting import caster_factory
    from rls_addon.core.scan.session import ScanSession

    fcd_path = tmp_path / "bus.xml"
    fcd_path.write_text(FCD_ONE_BUS)
    (tmp_path / "bus.vtypes.xml").write_text(VTYPES_BUS)
    scene.render.fps = 10
    ground(60.0)
    fcd, types = load(str(fcd_path))
    import_traffic(scene, fcd, types)
    lidar = add_lidar(location=(0.0, 0.0, 2.0))
    scene.frame_set(scene.frame_start)
    job = sensor_job(lidar, read_settings(lidar))
    session = ScanSession(caster_factory("bvhtree")[0])
    result, _ = session.scan(BlenderScene(scene), lidar.name, job.preset, job.settings.scan,
                             scene.frame_start)
    bus = bpy.data.objects["vehicle bus0"]
    assert bus.data.name  # imported
    on_bus = np.count_nonzero(result.points["label"] == label_id("vehicle"))
    assert on_bus > 200  # the warning's test is meaningful: many hits on the bus
    assert not [w for w in result.warnings if "inside" in w], result.warnings


def test_import_says_how_frames_map_to_sumo_steps(scene, tmp_path):
    """At 24 fps the import says how SUMO's 0.1 s steps map to frames; at 10 fps (a
    scene from rls scene from-net) it keys one frame per step and says nothing."""
    fcd_path = tmp_path / "bus.xml"
    fcd_path.write_text(FCD_ONE_BUS)
    (tmp_path / "bus.vtypes.xml").write_text(VTYPES_BUS)
    fcd, types = load(str(fcd_path))
    scene.render.fps, scene.render.fps_base = 24, 1.0
    info = import_traffic(scene, fcd, types)
    assert len(info["notices"]) == 1 and "24 fps" in info["notices"][0]
    bpy.ops.wm.read_factory_settings(use_empty=True)
    scene = bpy.context.scene
    scene.render.fps = 10
    info = import_traffic(scene, fcd, types)
    assert info["notices"] == [] and info["frames"] == 2


def test_elevated_traffic_is_refused_on_flat_roads_from_a_network(scene, tmp_path):
    """rls scene from-net builds flat roads (an elevated network is refused, with the
    advice to flatten it), but rls traffic generate ran on the elevated network and its
    FCD's z was keyed: on a network with one arm 6 m up, cars floated up to 5.8 m above
    the flattened scene's roads. A scene from rls scene from-net (it records
    rls_sumo_net_offset) refuses FCD with z before anything is added; another scene
    keys FCD's z as before."""
    from rls_addon.core.errors import InputError

    fcd_path = tmp_path / "bus.xml"
    fcd_path.write_text(FCD_ONE_BUS.replace('y="0.00" angle', 'y="0.00" z="2.45" angle', 1))
    (tmp_path / "bus.vtypes.xml").write_text(VTYPES_BUS)
    fcd, types = load(str(fcd_path))
    scene.render.fps = 10
    scene["rls_sumo_net_offset"] = [0.0, 0.0]
    with pytest.raises(InputError, match=r"bus0.*time 0 has z 2.45 m.*elevation.*flatten"):
        import_traffic(scene, fcd, types)
    assert "SUMO Traffic" not in bpy.data.collections
    del scene["rls_sumo_net_offset"]
    import_traffic(scene, fcd, types)
    scene.frame_set(scene.frame_start)
    assert bpy.data.objects["vehicle bus0"].location.z == pytest.approx(2.45)


FCD_WALK = """<?xml version="1.0" encoding="UTF-8"?>
<fcd-export>
    <timestep time="0.00">
        <person id="p0" x="0.10" y="0.00" angle="90.00" type="DEFAULT_PEDTYPE" speed="1.00" pos="0.00" edge="a" slope="0.00"/>
        <vehicle id="b0" x="0.80" y="-3.00" angle="90.00" type="DEFAULT_BIKETYPE" speed="4.00" pos="0.80" lane="a_0" slope="0.00"/>
        <vehicle id="c0" x="5.00" y="-1.00" angle="90.00" type="DEFAULT_VEHTYPE" speed="10.00" pos="5.00" lane="a_1" slope="0.00"/>
    </timestep>
    <timestep time="1.00">
        <person id="p0" x="8.10" y="0.00" angle="90.00" type="DEFAULT_PEDTYPE" speed="1.00" pos="8.00" edge="a" slope="0.00"/>
        <vehicle id="b0" x="8.80" y="-3.00" angle="90.00" type="DEFAULT_BIKETYPE" speed="4.00" pos="8.80" lane="a_0" slope="0.00"/>
        <vehicle id="c0" x="15.00" y="-1.00" angle="90.00" type="DEFAULT_VEHTYPE" speed="10.00" pos="15.00" lane="a_1" slope="0.00"/>
    </timestep>
</fcd-export>
"""


def test_people_and_bicycles_stand_on_the_surface_under_them(scene, tmp_path):
    """A person and a bicycle walk from the road (z = 0) onto a sidewalk raised 0.15 m
    (x >= 4); a car drives on the road. Their boxes' bottoms follow the surface under
    their centres: 0 on the road, 0.15 on the sidewalk (FCD's z is 0 all along); the
    car keeps FCD's z."""
    from .conftest import mesh_object

    road = mesh_object("Road", [(-20, -10, 0), (30, -10, 0), (30, 10, 0), (-20, 10, 0)],
                       [(0, 1, 2, 3)])
    road["rls_label"] = "road"
    kerb = 0.15
    walk = mesh_object("Sidewalk", [(4, -4, kerb), (30, -4, kerb), (30, 2, kerb),
                                    (4, 2, kerb)], [(0, 1, 2, 3)])
    walk["rls_label"] = "sidewalk"
    building = mesh_object("Roof", [(-20, -10, 0.3), (30, -10, 0.3), (30, 10, 0.3),
                                    (-20, 10, 0.3)], [(0, 1, 2, 3)])
    building["rls_label"] = "building"  # not ground: nobody stands on it
    fcd_path = tmp_path / "walk.xml"
    fcd_path.write_text(FCD_WALK)
    scene.render.fps = 10
    fcd, types = load(str(fcd_path))
    import_traffic(scene, fcd, types)
    for name, length in (("person p0", types["DEFAULT_PEDTYPE"].length),
                         ("vehicle b0", types["DEFAULT_BIKETYPE"].length)):
        obj = bpy.data.objects[name]
        for frame in range(1, 12):
            scene.frame_set(frame)
            x = obj.matrix_world.translation.x
            want = kerb if x >= 4.0 else 0.0
            assert obj.matrix_world.translation.z == pytest.approx(want, abs=1e-5), \
                (name, frame, x)
    car = bpy.data.objects["vehicle c0"]
    scene.frame_set(11)
    assert car.matrix_world.translation.z == pytest.approx(0.0, abs=1e-6)


def test_traffic_span_is_the_keyed_frames(scene, tmp_path):
    """The imported road users' keys span the frames the import keyed (1-11 for 1 s at
    10 fps); a road user keyed once (not moving) does not count."""
    from rls_addon.blender.source import traffic_span
    from .conftest import mesh_object

    assert traffic_span(scene) is None
    still = mesh_object("Parked", [(0, 0, 0), (1, 0, 0), (1, 1, 0)], [(0, 1, 2)])
    still["rls_label"] = "vehicle"
    still.keyframe_insert("location", frame=1)
    assert traffic_span(scene) is None
    fcd_path = tmp_path / "walk.xml"
    fcd_path.write_text(FCD_WALK)
    scene.render.fps = 10
    fcd, types = load(str(fcd_path))
    info = import_traffic(scene, fcd, types)
    assert traffic_span(scene) == (info["first_frame"], info["last_frame"]) == (1, 11)

"""The fixed inputs behind the golden checksums (see ``record.py``)."""

import numpy as np


def core_scene():
    """A ground, a glossy wall, a box and a car driving 15 m/s past a still sensor."""
    from rls_addon.core.scene.geometry import MaterialInfo
    from tests.core.scenes import box_geometry, merge

    mirror = MaterialInfo("mirror", 0.9, glossy=True, ghost_ratio=0.5)
    ground = box_geometry((-40, -40, -1.6), (40, 40, -1.5), label=1, instance=1, name="ground")
    wall = box_geometry((12.0, -20, -1.5), (12.2, 20, 4), label=13, instance=2, name="glass",
                        material=mirror)
    box = box_geometry((-6.0, 3, -1.5), (-4.0, 5, 0.5), label=4, instance=3, name="bin")
    static = merge(ground, wall, box)
    car = box_geometry((-2.25, -0.9, -1.2), (2.25, 0.9, 0.3), label=11, instance=4, name="car")
    return static, car


def core_scan(mode, substeps, space):
    from rls_addon.core.world.bodies import PreparedScene, RigidBodies
    from rls_addon.core.scan.frame import scan_frame
    from rls_addon.core.scan.settings import ScanSettings
    from rls_addon.core.scene.motion import Track
    from rls_addon.core.device.patterns.spinning import spinning_pattern
    from rls_addon.core.device.presets import DevicePreset, DropoutModel, RangeModel
    from rls_addon.core.casting import NumpyCaster

    preset = DevicePreset(id="g", name="g", family="spinning", source="golden",
                          frequency_hz=10.0, range=RangeModel(0.3, 60.0, 0.02),
                          dropout=DropoutModel(0.05, 0.1, 0.4))
    pattern = spinning_pattern(np.linspace(-15, 10, 16), 10.0, 16 * 900 * 10)
    static, car = core_scene()
    times = np.linspace(0.0, 0.1, 5)
    mats = np.repeat(np.eye(4)[None], 5, axis=0)
    mats[:, 0, 3] = -3.0 + 15.0 * times
    mats[:, 1, 3] = 6.0
    body = RigidBodies([(car, Track(times, mats))], NumpyCaster)
    settings = ScanSettings(seed=11, frame_space=space, motion=mode, substeps=substeps)
    pose = np.eye(4)
    c, s_ = np.cos(0.3), np.sin(0.3)
    pose[:2, :2] = [[c, -s_], [s_, c]]
    pose[:3, 3] = (0.5, -0.3, 0.2)
    scene = PreparedScene(static, pose[:3, 3], 60.0, NumpyCaster)
    return scan_frame(scene, pattern, pose, preset, settings, frame=3, sensor="golden",
                      moving=[body]).points


EFFECT_CASES = {
    "equation": {},
    "footprint_dual": {"footprint": "auto", "return_mode": "dual"},
    "fog50": {"weather": "fog:visibility=50"},
    "rain_footprint": {"weather": "rain:rate=30", "footprint": "auto",
                       "return_mode": "dual"},
}


def effect_scan(case, space):
    """The still sensor of ``core_scan`` over its static scene, as a Velodyne HDL-64E
    (datasheet figures: the LiDAR equation) with a wide 10 mrad beam (so that the box's
    and the wall's edges split many footprints: ~950 rays changed, 16 with two echoes)
    on a 16-channel pattern, with the effects of issue 21 (``EFFECT_CASES``). Recorded
    2026-11-23 with the code of e0fd755 (before the per-hit stage of these frames moved
    to C) and checked against the code of 7bb9e5b."""
    import dataclasses

    from rls_addon.core.world.bodies import PreparedScene
    from rls_addon.core.casting import NumpyCaster
    from rls_addon.core.physics.footprint import Beam
    from rls_addon.core.scan.frame import scan_frame
    from rls_addon.core.device.patterns.spinning import spinning_pattern
    from rls_addon.core.device.presets import get_preset
    from rls_addon.core.scan.settings import ScanSettings

    preset = dataclasses.replace(get_preset("velodyne_hdl64e"),
                                 beam=Beam((0.01, 0.01), "strongest", 1.0))
    pattern = spinning_pattern(np.linspace(-15, 10, 16), 10.0, 16 * 1200 * 10)
    static, _ = core_scene()
    pose = np.eye(4)
    pose[:3, 3] = (0.5, -0.3, 0.2)
    scene = PreparedScene(static, pose[:3, 3], preset.range.max_m, NumpyCaster)
    settings = ScanSettings(seed=5, frame_space=space, **EFFECT_CASES[case])
    return scan_frame(scene, pattern, pose, preset, settings, frame=2, sensor="golden").points


def _street():
    import bpy

    from rls_addon.blender.sample_scene import build_street

    bpy.ops.wm.read_factory_settings(use_empty=True)
    import rls_addon

    if not hasattr(bpy.types.Object, "rls_lidar"):
        rls_addon.register()
    scene = bpy.context.scene
    scene.name = "street"
    mount = build_street(scene)
    lidar = bpy.data.objects.new("LiDAR", None)
    lidar.location = mount
    lidar.rotation_euler = (0.0, 0.17453292519943295, -1.5707963267948966)
    scene.collection.objects.link(lidar)
    lidar.rls_lidar.is_lidar = True
    lidar.rls_lidar.preset_id = "hesai_pandar64"
    lidar.rls_lidar.seed = 5
    return scene, lidar


def blender_street_scans():
    """[(name, points)] of the demo street's pole lidar, frames 1 and 9, both backends,
    exact and snapshot motion."""
    from rls_addon.blender.scan import scan_lidar
    from rls_addon.blender.source import BlenderScene
    from rls_addon.core.casting import caster_factory
    from rls_addon.core.scan.session import ScanSession

    out = []
    scene, lidar = _street()
    for backend in ("bvhtree", "embree"):
        for motion in ("exact", "snapshot"):
            lidar.rls_lidar.motion = motion
            session, source = ScanSession(caster_factory(backend)[0]), BlenderScene(scene)
            for frame in (1, 9):
                result, _ = scan_lidar(lidar, frame, session=session, source=source)
                out.append((f"street/{backend}/{motion}/{frame}", result.points))
    lidar.rls_lidar.motion = "exact"
    return out


def junction_study():
    """(per-candidate rows, best sets) of a small study on the sample T-junction."""
    import bpy

    import rls_addon
    from rls_addon.blender.scenes import build_scene
    from rls_addon.blender.study import run_study
    from rls_addon.core.study.config import StudyConfig

    bpy.ops.wm.read_factory_settings(use_empty=True)
    if not hasattr(bpy.types.Object, "rls_lidar"):
        rls_addon.register()
    build_scene("t_junction", bpy.context.scene)
    cfg = StudyConfig(device="generic_uniform32", k=(1, 2),
                      mounts=("TL NE", "TL NW", "TL SE", "SL S"), pitches=(0.0, 15.0),
                      backend="bvhtree", disks=500)
    res = run_study(bpy.context.scene, cfg)
    rows = [[c.name, c.n_points, c.scan_points, repr(c.infra_d), repr(c.infra_nuc)]
            for c in res.candidates]
    best = {str(k): [list(s.best.members), repr(s.best.infra_d), repr(s.best.infra_nuc),
                     len(s.front)] for k, s in res.searches.items()}
    return rows, best

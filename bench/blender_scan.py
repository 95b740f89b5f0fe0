"""A LiDAR in Blender over the 1M-triangle street, through the add-on's scan session:
standing still (scene extraction included, the static cast reused) and driving: the
report's section *In Blender*."""

import time

from bench.timing import best, ms


def measure(g, pose, device="hesai_pandar64", frames=6):
    """A lidar standing still in Blender over the 1M-triangle street: what a frame costs
    through the add-on's scan session, scene extraction included."""
    import bpy

    import rls_addon
    from bench.scene import add_to_blender
    from rls_addon.blender.extract import read_instances
    from rls_addon.blender.scan import scan_lidar
    from rls_addon.blender.source import BlenderScene
    from rls_addon.core.world.bodies import PreparedScene
    from rls_addon.core.casting import EmbreeCaster
    from rls_addon.core.scan.session import MOVER_MARGIN_M, ScanSession

    rls_addon.register()
    try:
        scene = bpy.context.scene
        add_to_blender(g, scene)
        lidar = bpy.data.objects.new("LiDAR", None)
        lidar.matrix_world = [list(r) for r in pose]
        scene.collection.objects.link(lidar)
        lidar.rls_lidar.is_lidar, lidar.rls_lidar.preset = True, device
        session, source = ScanSession(EmbreeCaster), BlenderScene(scene)
        scene.frame_set(1)
        t = time.perf_counter()
        scan_lidar(lidar, 1, session=session, source=source)
        first = time.perf_counter() - t
        PreparedScene.reuse_casts = True  # what a still lidar's later frames do
        later = []
        for f in range(2, frames + 1):
            scene.frame_set(f)
            t = time.perf_counter()
            res, info = scan_lidar(lidar, f, session=session, source=source)
            later.append(time.perf_counter() - t)
        PreparedScene.reuse_casts = False
        dg = bpy.context.evaluated_depsgraph_get()
        rmax = info["effects"]["range_m"][1] + MOVER_MARGIN_M
        from rls_addon.blender import extract as ex

        extract = {}
        for name, reader in (("every mesh read", None), ("session reader", source.meshes)):
            extract[name], _ = best(lambda: read_instances(dg, pose[:3, 3], rmax, {"LiDAR"},
                                                           reader=reader), 3)
        arrays, ex._attribute_arrays = ex._attribute_arrays, lambda mesh: None
        try:  # Blender's per-item accessors (older Blenders; what RLS read before)
            extract["every mesh read item by item"], _ = best(
                lambda: read_instances(dg, pose[:3, 3], rmax, {"LiDAR"}), 2)
        finally:
            ex._attribute_arrays = arrays
        # The same lidar driving along the street at 10 m/s (exact motion: every ray
        # from where the lidar was when it fired).
        fps = scene.render.fps / scene.render.fps_base
        for f, x in ((1, pose[0, 3]), (101, pose[0, 3] + 1000.0 / fps)):
            lidar.location.x = x
            lidar.keyframe_insert("location", index=0, frame=f)
        for fc in _fcurves(lidar):
            for kp in fc.keyframe_points:
                kp.interpolation = "LINEAR"
        drive, builds = [], session.builds
        for f in range(1, frames + 1):
            scene.frame_set(f)
            t = time.perf_counter()
            _, dinfo = scan_lidar(lidar, f, session=session, source=source)
            drive.append(time.perf_counter() - t)
        return {"first_s": first, "later_s": min(later), "reused": res.stats["static_cast_reused"],
                "extract_s": extract, "objects": info["objects_read"],
                "driving_s": drive, "driving_builds": session.builds - builds,
                "driving_moves": bool(dinfo["motion"].get("sensor_moves"))}
    finally:
        PreparedScene.reuse_casts = False
        for ob in list(bpy.data.objects):
            bpy.data.objects.remove(ob)
        for mesh in list(bpy.data.meshes):
            bpy.data.meshes.remove(mesh)
        rls_addon.unregister()


def _fcurves(obj):
    """The F-curves of an object's action (Blender 4.4+ keeps them in slot channelbags)."""
    from bpy_extras import anim_utils

    ad = obj.animation_data
    bag = anim_utils.action_get_channelbag_for_slot(ad.action, ad.action_slot)
    return bag.fcurves


def section(b):
    """A still and a driving lidar in Blender, extraction included (none when ``b``, the
    numbers of ``measure``, is empty)."""
    L = []
    if b:
        L.append("## In Blender\n")
        L.append(f"The same street as {b['objects']} Blender mesh objects (`bench/scene.py:"
                 "add_to_blender`; labelled, without materials, so nothing is glossy and "
                 "no ghost rays are cast) and a Pandar64 lidar standing still at the same pose, "
                 "scanned frame after frame through the add-on's scan session (Embree, "
                 "default settings, scene extraction included). Extraction copies "
                 "positions, corners and face materials out of Blender's attribute arrays "
                 "(this street is all triangles, so that is all it reads; meshes with "
                 "quads or n-gons also need Blender's triangulation, read per triangle, "
                 "which the session's `extract.MeshReader` skips for a mesh unchanged "
                 "since it was last read). Later frames key the static scene by mesh ids "
                 "instead of joining and digesting its triangles, and reuse the static "
                 "cast.\n")
        L.append("| | ms |")
        L.append("|---|---|")
        L.append(f"| first frame (extraction, Embree build, scan) | {ms(b['first_s'])} |")
        L.append(f"| later frame, best of five (static cast reused: {b['reused']}) | "
                 f"{ms(b['later_s'])} |")
        for name, s in b["extract_s"].items():
            L.append(f"| extraction alone, {name} | {ms(s)} |")
        if "driving_s" in b:
            d = b["driving_s"]
            L.append(f"| the lidar driving at 10 m/s (exact motion): first frame, second "
                     f"frame (the scene prepared wider, `DRIVING_SLACK`), later frames best "
                     f"| {ms(d[0])}, {ms(d[1])}, {ms(min(d[2:]))} "
                     f"({b['driving_builds']} builds in {len(d)} frames) |")
        L.append("")
    return L

"""SUMO traffic in a Blender scene: one animated object per vehicle and person of an
FCD file (``rls traffic import``, *Import SUMO Traffic*).

Every object is a low-poly mesh of its class (car, van, truck, bus, motorcycle,
bicycle, pedestrian: a side profile extruded across the width, made here from
numbers), whose own box is exactly its vType's length x width x height along local
x, y, z, with the origin on the ground under the box's centre. RLS's ground truth takes
an object's box from its mesh's bounds in its own axes (``core.output.ground_truth``),
so the box is the vType's size and its centre the FCD position converted by
``core.traffic.fcd`` (plus half the height). Objects of one vType share one mesh.

Motion is keyed at the scene's frames with F-curves filled in bulk (``foreach_set``):
location x, y, z and rotation z, LINEAR, only over the frames the object is present
(F-curves hold their end values outside their keys). Presence is ``hide_render`` and
``hide_viewport`` keyed CONSTANT: hidden before the object appears and from the first
frame after it leaves. RLS reads which objects exist once per scan, at the frame
(``extract.read_instances`` skips objects hidden from render), so an object that is
present at a frame is scanned over that whole sweep and one that is absent is not.
"""


import bpy
import numpy as np

from ..core.errors import SceneError
from ..core.traffic.fcd import (
    check_flat,
    check_origin,
    check_positions,
    frame_times,
    keyed_frames,
    resample,
    step_notice,
)
from ..core.traffic.ground import STANDING_LABELS

COLLECTION = "SUMO Traffic"

# Side profiles (x along the length from -0.5 at the back to 0.5 at the front, z from 0
# to 1), each touching all four sides of the unit square so the mesh's box is exact.
PROFILES = {
    "car": [(-0.5, 0.0), (0.5, 0.0), (0.5, 0.42), (0.28, 0.55), (0.12, 1.0),
            (-0.32, 1.0), (-0.5, 0.58)],
    "van": [(-0.5, 0.0), (0.5, 0.0), (0.5, 0.5), (0.32, 1.0), (-0.5, 1.0)],
    "truck": [(-0.5, 0.0), (0.5, 0.0), (0.5, 0.82), (0.26, 0.86), (0.24, 1.0),
              (-0.5, 1.0)],
    "bus": [(-0.5, 0.0), (0.5, 0.0), (0.5, 0.94), (0.46, 1.0), (-0.5, 1.0)],
    "motorcycle": [(-0.5, 0.0), (0.5, 0.0), (0.5, 0.45), (0.18, 0.62), (0.05, 1.0),
                   (-0.18, 1.0), (-0.5, 0.5)],
    "bicycle": [(-0.5, 0.0), (0.5, 0.0), (0.42, 0.6), (0.12, 1.0), (-0.2, 1.0),
                (-0.5, 0.55)],
    "pedestrian": [(-0.5, 0.0), (0.5, 0.0), (0.5, 0.8), (0.22, 0.86), (0.22, 1.0),
                   (-0.22, 1.0), (-0.22, 0.86), (-0.5, 0.8)],
}
COLOURS = {"car": (0.55, 0.06, 0.05), "van": (0.8, 0.8, 0.78), "truck": (0.15, 0.3, 0.6),
           "bus": (0.9, 0.6, 0.1), "motorcycle": (0.1, 0.1, 0.1),
           "bicycle": (0.2, 0.5, 0.2), "pedestrian": (0.35, 0.3, 0.6)}


def profile_mesh(name, shape, size):
    """A mesh: ``shape``'s profile scaled to ``size`` (length, width, height), extruded
    across the width; its bounds are exactly [-L/2, L/2] x [-W/2, W/2] x [0, H]. Its
    faces are wound so their normals point out of the solid (positive signed volume):
    a profile is counter-clockwise seen from -y, so the side at -y keeps its order, the
    side at +y is reversed, and each band runs from the +y side to the -y side."""
    L, W, H = map(float, size)
    prof = PROFILES[shape]
    n = len(prof)
    verts = [(x * L, side * W / 2, z * H) for side in (-1.0, 1.0) for x, z in prof]
    faces = [list(range(n)), list(range(n, 2 * n))[::-1]]
    faces += [[n + i, n + (i + 1) % n, (i + 1) % n, i] for i in range(n)]
    mesh = bpy.data.meshes.new(name)
    mesh.from_pydata(verts, [], faces)
    mesh.update()
    return mesh


def _material(shape):
    name = f"SUMO {shape}"
    mat = bpy.data.materials.get(name)
    if mat is None:
        mat = bpy.data.materials.new(name)
        mat.diffuse_color = (*COLOURS[shape], 1.0)
        mat.roughness = 0.4
    return mat


def _enum(name):
    return bpy.types.Keyframe.bl_rna.properties["interpolation"].enum_items[name].value


def _fill(action, obj, path, index, frames, values, interp):
    fc = action.fcurve_ensure_for_datablock(obj, path, index=index)
    n = len(frames)
    fc.keyframe_points.add(n)
    co = np.empty(2 * n, np.float32)
    co[0::2], co[1::2] = frames, values
    fc.keyframe_points.foreach_set("co", co)
    fc.keyframe_points.foreach_set("interpolation", np.full(n, interp, np.int32))
    fc.update()
    return fc


def key_presence(action, obj, frames, motion):
    """``hide_render`` and ``hide_viewport`` keyed CONSTANT: at the scene's first frame,
    where presence changes, and at the first frame after the object leaves."""
    present = motion.present
    change = np.r_[True, present[1:] != present[:-1]]
    f = list(frames[motion.first:motion.stop][change])
    hidden = list((~present[change]).astype(np.float64))
    if motion.first > 0:
        f.insert(0, frames[0])
        hidden.insert(0, 1.0)
    if motion.stop < len(frames):
        f.append(frames[motion.stop])
        hidden.append(1.0)
    constant = _enum("CONSTANT")
    for path in ("hide_render", "hide_viewport"):
        _fill(action, obj, path, 0, np.asarray(f, np.float64), np.asarray(hidden), constant)


def key_object(obj, frames, motion):
    """Key ``obj``'s motion (``core.traffic.fcd.Motion``) at ``frames`` (those of the
    times it was resampled at)."""
    f = frames[motion.first:motion.stop].astype(np.float64)
    xyz, yaw = motion.xyz, motion.yaw
    obj.location = tuple(map(float, xyz[0]))
    obj.rotation_euler = (0.0, 0.0, float(yaw[0]))
    obj.animation_data_create()
    action = bpy.data.actions.new(f"{obj.name} motion")
    obj.animation_data.action = action
    linear = _enum("LINEAR")
    for i in range(3):
        _fill(action, obj, "location", i, f, xyz[:, i], linear)
    _fill(action, obj, "rotation_euler", 2, f, yaw, linear)
    key_presence(action, obj, frames, motion)


def traffic_origin(scene, requested=None):
    """The network point that lands on the scene's origin: ``requested`` (X, Y), else
    the one the scene records (``rls_sumo_origin``: a scene built by ``rls scene
    from-net``, or traffic imported before), else (0, 0), network coordinates. A
    requested origin other than the recorded one is refused: the traffic would miss the
    roads."""
    check_origin(requested)
    recorded = scene.get("rls_sumo_origin")
    recorded = None if recorded is None else (float(recorded[0]), float(recorded[1]))
    if requested is None:
        return recorded or (0.0, 0.0)
    requested = (float(requested[0]), float(requested[1]))
    if recorded is not None and max(abs(a - b) for a, b in zip(requested, recorded)) > 1e-6:
        raise SceneError(
            f"the scene places network point ({recorded[0]:g}, {recorded[1]:g}) at its origin "
            f"(rls_sumo_origin, from rls scene from-net or an earlier import), not "
            f"({requested[0]:g}, {requested[1]:g}): traffic there would miss its roads; "
            f"leave the origin out to use the scene's")
    return requested


def scene_ground(scene):
    """The scene's ground surfaces (``core.traffic.ground``: objects labelled road,
    sidewalk, terrain or ground, as rendered now) to stand people and bicycles on."""
    from ..core.casting import caster_factory
    from ..core.labels import label_id
    from ..core.scene.instances import object_table, world_geometry
    from ..core.traffic.ground import GROUND_LABELS, GroundSurface
    from .extract import read_instances

    instances, materials, _ = read_instances(bpy.context.evaluated_depsgraph_get())
    labels = {label_id(n) for n in GROUND_LABELS}
    flat = [i for i in instances if i.label in labels]
    geo = world_geometry(flat, object_table(flat), materials)
    return GroundSurface(geo.vertices, geo.triangles, caster_factory("auto")[0])


def import_traffic(scene, fcd, types, origin=(0.0, 0.0), begin=None, end=None,
                   progress=None, ground=None):
    """Animated objects for every track of ``fcd`` (``core.traffic.fcd.Fcd``) with
    sizes ``types`` ({type id: VType}) in ``scene``, in a new collection. Frame
    ``scene.frame_start`` is simulation time ``begin`` (default: the FCD's first step);
    frames are keyed up to ``end`` (default its last step), and the scene's last frame
    is set to the last keyed one. ``progress(done, total)`` is called as objects are
    made. ``ground(xy (N, 2)) -> (N,)`` heights added to FCD's z of every object (a
    sample scene's own kerbs); without it, pedestrians and cyclists stand on the scene's
    ground surfaces under them (``scene_ground``; vehicles keep FCD's z). Returns a
    summary dict."""
    fps = scene.render.fps / scene.render.fps_base
    begin, end, n = keyed_frames(fcd, fps, scene.frame_start, begin, end)
    check_origin(origin)
    check_positions(fcd, types, origin)  # all before anything is added to the scene
    if scene.get("rls_sumo_net_offset") is not None:  # roads from rls scene from-net
        from ..core.roads.network import FLAT_TOLERANCE_M

        check_flat(fcd, FLAT_TOLERANCE_M, "the scene's roads (rls scene from-net) are "
                   "flat at z = 0")
    times = frame_times(n, fps, begin)
    frames = scene.frame_start + np.arange(n)
    coll = bpy.data.collections.new(COLLECTION)
    scene.collection.children.link(coll)
    meshes = {}
    counts = {"vehicle": 0, "pedestrian": 0, "cyclist": 0}
    object_frames = 0
    keys = sorted(fcd.tracks)
    surface = scene_ground(scene) if ground is None else None
    for j, key in enumerate(keys):
        tr = fcd.tracks[key]
        vt = types[tr.type]
        motion = resample(tr, vt.length, times, fcd.step, origin)
        if progress is not None and j % 25 == 0:
            progress(j, len(keys))
        if motion is None:
            continue
        if ground is not None:
            motion.xyz[:, 2] += ground(motion.xyz[:, :2])
        elif vt.label in STANDING_LABELS:
            motion.xyz[:, 2] = surface.heights(motion.xyz[:, :2], motion.xyz[:, 2])
        mesh = meshes.get(vt.id)
        if mesh is None:
            mesh = meshes[vt.id] = profile_mesh(f"SUMO {vt.id}", vt.shape, vt.size)
            mesh.materials.append(_material(vt.shape))
        name = f"{'person' if tr.kind == 'person' else 'vehicle'} {tr.id}"
        obj = bpy.data.objects.new(name, mesh)
        coll.objects.link(obj)
        obj["rls_label"] = vt.label
        obj["sumo_id"] = tr.id
        obj["sumo_type"] = vt.id
        key_object(obj, frames, motion)
        counts[vt.label] += 1
        object_frames += int(motion.present.sum())
    scene.frame_end = int(frames[-1])
    scene["rls_sumo_origin"] = [float(origin[0]), float(origin[1])]
    scene["rls_sumo_begin_s"] = float(begin)
    if progress is not None:
        progress(len(keys), len(keys))
    notice = step_notice(fps, fcd.step, begin, scene.frame_start)
    return {"collection": coll.name, "objects": sum(counts.values()), **counts,
            "frames": n, "first_frame": int(frames[0]), "last_frame": int(frames[-1]),
            "object_frames": object_frames, "begin_s": begin, "end_s": end,
            "fps": fps, "fcd_step_s": fcd.step, "notices": [notice] if notice else []}

"""Building blocks for procedural scenes, with ``bpy.data`` only (no operators), so
they run the same in the UI, ``blender -b`` and the ``bpy`` module.

Conventions the rest of RLS reads:

* labels come from collection names (Road, Sidewalk, Buildings, Poles,
  Traffic Lights, Vehicles, Pedestrians, Cyclists; see ``core/labels.py``);
* LiDAR mounts are pole objects with the custom property ``rls_mount = True``; the
  mount position is the top centre of the pole plus ``rls_mount_offset`` metres
  (default ``MOUNT_OFFSET_M``) so a sensor sits clear of the pole's cap;
* the region of interest is a flat mesh with ``rls_infralob = True``, hidden from
  render (it is never scanned);
* a glass facade is a material with ``rls_glossy = True``, metallic 1 and
  roughness 0.02, which makes ghost points.
"""

import bpy
import numpy as np

from ...core.labels import base_name

# Outward-facing windings (counter-clockwise seen from outside): the engine warns when
# a sensor sees mostly the backs of faces, as it would from inside an inward box.
BOX_FACES = [(0, 3, 2, 1), (4, 5, 6, 7), (0, 1, 5, 4), (1, 2, 6, 5), (2, 3, 7, 6), (3, 0, 4, 7)]
MOUNT_PROPERTY = "rls_mount"
MOUNT_OFFSET_PROPERTY = "rls_mount_offset"
MOUNT_OFFSET_M = 0.25


def collection(scene, name):
    """``scene``'s collection called ``name`` (or ``name.001``, ...: Blender's name for it
    when another scene of the file has a ``name``), at any depth, made and linked if it
    has none. A collection of another scene is never reused: its objects would join
    this one."""
    for coll in scene.collection.children_recursive:
        if base_name(coll.name) == name:
            return coll
    coll = bpy.data.collections.new(name)
    scene.collection.children.link(coll)
    return coll


def material(name, rgb, roughness=0.5, metallic=0.0, reflectivity=None, glossy=None):
    """A material whose viewport settings and Principled BSDF agree (renders and the
    LiDAR's glossy detection see the same surface)."""
    mat = bpy.data.materials.get(name) or bpy.data.materials.new(name)
    mat.diffuse_color = (*rgb, 1.0)
    mat.roughness = roughness
    mat.metallic = metallic
    nodes = mat.node_tree.nodes if mat.node_tree is not None else []
    for node in nodes:
        if node.type == "BSDF_PRINCIPLED":
            node.inputs["Base Color"].default_value = (*rgb, 1.0)
            node.inputs["Roughness"].default_value = roughness
            node.inputs["Metallic"].default_value = metallic
    if reflectivity is not None:
        mat["rls_reflectivity"] = reflectivity
    if glossy is not None:
        mat["rls_glossy"] = bool(glossy)
    return mat


def standard_materials():
    """The materials the sample scenes share, by role."""
    return {
        "asphalt": material("Asphalt", (0.08, 0.08, 0.08), reflectivity=0.15),
        "concrete": material("Concrete", (0.5, 0.5, 0.48), reflectivity=0.45),
        "facade": material("Facade", (0.6, 0.55, 0.5)),
        "glass": material("Glass", (0.8, 0.85, 0.9), roughness=0.02, metallic=1.0, glossy=True),
        "paint": material("CarPaint", (0.6, 0.05, 0.05), roughness=0.2),
        "steel": material("Steel", (0.55, 0.55, 0.55), roughness=0.3, metallic=1.0),
    }


def mesh_object(coll, name, verts, faces, mat):
    mesh = bpy.data.meshes.new(name)
    mesh.from_pydata([tuple(map(float, v)) for v in verts], [], faces)
    mesh.update()
    if mat is not None:
        mesh.materials.append(mat)
    obj = bpy.data.objects.new(name, mesh)
    coll.objects.link(obj)
    return obj


def box(coll, name, lo, hi, mat):
    (x0, y0, z0), (x1, y1, z1) = lo, hi
    verts = [(x0, y0, z0), (x1, y0, z0), (x1, y1, z0), (x0, y1, z0),
             (x0, y0, z1), (x1, y0, z1), (x1, y1, z1), (x0, y1, z1)]
    return mesh_object(coll, name, verts, BOX_FACES, mat)


def cylinder(coll, name, centre, radius, height, mat, segments=16):
    a = np.linspace(0, 2 * np.pi, segments, endpoint=False)
    cx, cy, cz = centre
    ring = [(cx + radius * np.cos(t), cy + radius * np.sin(t)) for t in a]
    verts = [(x, y, cz) for x, y in ring] + [(x, y, cz + height) for x, y in ring]
    n = segments
    faces = [(i, (i + 1) % n, (i + 1) % n + n, i + n) for i in range(n)]
    faces += [tuple(range(n - 1, -1, -1)), tuple(range(n, 2 * n))]
    return mesh_object(coll, name, verts, faces, mat)


def plane(coll, name, x0, x1, y0, y1, z, mat, cuts=1):
    xs, ys = np.linspace(x0, x1, cuts + 1), np.linspace(y0, y1, cuts + 1)
    verts = [(x, y, z) for y in ys for x in xs]
    w = cuts + 1
    faces = [(j * w + i, j * w + i + 1, (j + 1) * w + i + 1, (j + 1) * w + i)
             for j in range(cuts) for i in range(cuts)]
    return mesh_object(coll, name, verts, faces, mat)


def mount_pole(coll, name, x, y, height, mat, kind, arm_towards=None, arm_length=4.0,
               base_z=0.15):
    """A pole marked as a LiDAR mount (``rls_mount``); ``kind`` is recorded as
    ``rls_mount_kind``. A traffic-light pole gets a mast arm (a separate, unmarked
    object, 0.6 m below the top) reaching ``arm_length`` metres towards the xy point
    ``arm_towards``."""
    pole = cylinder(coll, name, (x, y, base_z), 0.12, height, mat, segments=12)
    pole[MOUNT_PROPERTY] = True
    pole["rls_mount_kind"] = kind
    if arm_towards is not None:
        d = np.asarray(arm_towards, float) - (x, y)
        d /= np.linalg.norm(d) or 1.0
        z = base_z + height - 0.6
        end = np.array([x, y]) + d * arm_length
        lo = np.minimum((x, y), end) - 0.08
        hi = np.maximum((x, y), end) + 0.08
        box(coll, f"{name} arm", (lo[0], lo[1], z - 0.08), (hi[0], hi[1], z + 0.08), mat)
    return pole


def infralob(scene, name, x0, x1, y0, y1, mat=None):
    """The region of interest: a flat rectangle marked ``rls_infralob``, never rendered."""
    coll = collection(scene, "Regions")
    lob = plane(coll, name, x0, x1, y0, y1, 0.02, mat)
    lob["rls_infralob"] = True
    lob.hide_render = True
    lob.display_type = "WIRE"
    return lob


def car(coll, name, mat, path, frames, size=(4.5, 1.8, 1.5)):
    """A box car keyframed through the xy points ``path`` at ``frames``, heading along
    each leg (linear interpolation, so it drives at constant speed per leg)."""
    L, W, H = size
    obj = box(coll, name, (-L / 2, -W / 2, 0.3), (L / 2, W / 2, 0.3 + H), mat)
    pts = [np.asarray(p, float) for p in path]
    legs = [pts[i + 1] - pts[i] for i in range(len(pts) - 1)]
    legs.append(legs[-1])
    heading = np.unwrap([np.arctan2(d[1], d[0]) for d in legs])  # turn the short way
    for p, f, yaw in zip(pts, frames, heading):
        obj.location = (float(p[0]), float(p[1]), 0.0)
        obj.rotation_euler = (0.0, 0.0, float(yaw))
        obj.keyframe_insert("location", frame=int(f))
        obj.keyframe_insert("rotation_euler", frame=int(f))
    if obj.animation_data and obj.animation_data.action:
        _linear(obj.animation_data.action)
    return obj


def action_curves(action):
    """Every F-curve of ``action`` (Blender 5 keeps them in layered actions)."""
    curves = list(getattr(action, "fcurves", []) or [])
    if not curves:
        for layer in getattr(action, "layers", []):
            for strip in layer.strips:
                for bag in getattr(strip, "channelbags", []):
                    curves += list(bag.fcurves)
    return curves


def _linear(action):
    """Linear keyframe interpolation."""
    for fc in action_curves(action):
        for kp in fc.keyframe_points:
            kp.interpolation = "LINEAR"


def mount_position(obj):
    """World (x, y, z) where a LiDAR sits on mount object ``obj``: the top centre of its
    world bounding box plus ``rls_mount_offset`` (an empty's own location is used as is)."""
    m = np.array(obj.matrix_world, dtype=np.float64)
    if obj.type == "EMPTY":
        return tuple(float(v) for v in m[:3, 3])
    corners = np.array([tuple(c) for c in obj.bound_box], dtype=np.float64)
    w = corners @ m[:3, :3].T + m[:3, 3]
    lo, hi = w.min(0), w.max(0)
    off = float(obj.get(MOUNT_OFFSET_PROPERTY, MOUNT_OFFSET_M))
    return (float((lo[0] + hi[0]) / 2), float((lo[1] + hi[1]) / 2), float(hi[2] + off))


def lidar_object(scene, name, preset, parent=None, location=(0, 0, 0), rotation=(0, 0, 0),
                 seed=None):
    """An empty in ``scene`` made a LiDAR of device ``preset`` (its ``rls_lidar``
    settings), at ``location`` with Euler ``rotation`` (radians), relative to ``parent``
    if given (a car it rides on)."""
    ob = bpy.data.objects.new(name, None)
    ob.location, ob.rotation_euler = location, rotation
    scene.collection.objects.link(ob)
    if parent is not None:
        ob.parent = parent
    s = ob.rls_lidar
    s.is_lidar, s.preset_id = True, preset
    if seed is not None:
        s.seed = seed
    return ob


def is_mount(obj):
    try:
        return bool(obj.get(MOUNT_PROPERTY, False))
    except (AttributeError, TypeError):
        return False

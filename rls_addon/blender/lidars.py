"""LiDAR objects made, listed and removed, with ``bpy.data`` only: what ``rls lidar
add|list|remove``, *Add > LiDAR*, the sample scenes and ``rls demo`` do to a scene.
Where the LiDAR goes is the core's ``scene.mounting.LidarMounting``."""

import math

import bpy
import numpy as np

from ..core.errors import SceneError
from ..core.metrics.polygon import polygon_centroid
from .fov import fov_object
from .preview import preview_object
from .region import lob_polygon_world
from .scenes.build import is_mount, mount_position
from .sensor import find_lidar, lidar_objects, lidar_props


def new_lidar(scene, name, preset_id, location=(0.0, 0.0, 0.0), rotation=(0.0, 0.0, 0.0),
              collection=None, show_fov=True, exact_name=True):
    """An empty in ``collection`` (default: the scene's own) made a LiDAR of device
    ``preset_id`` at ``location`` with XYZ Euler ``rotation`` (radians); its field of
    view outlined when ``show_fov``. The object is called ``name`` exactly: a taken name
    is refused (Blender would call it ``name.001``), unless ``exact_name`` is False (the
    UI, where Blender's numbering is what a user expects)."""
    if exact_name and bpy.data.objects.get(name) is not None:
        raise SceneError(f"the file already has an object named {name!r}: give the LiDAR "
                         "another name (--name)")
    obj = bpy.data.objects.new(name, None)
    obj.empty_display_type = "ARROWS"
    obj.empty_display_size = 0.5
    obj.location = tuple(float(v) for v in location)
    obj.rotation_euler = tuple(float(v) for v in rotation)
    (collection or scene.collection).objects.link(obj)
    s = lidar_props(obj)
    s.is_lidar = True
    s.preset_id = preset_id
    s.show_fov = show_fov  # its update draws the outline
    return obj


def find_mount(scene, name):
    """The object called ``name`` (a LiDAR sits on its top), with an error that lists the
    scene's mounts (objects marked ``rls_mount``)."""
    obj = scene.objects.get(name)
    if obj is None:
        mounts = sorted(o.name for o in scene.objects if is_mount(o))
        raise SceneError(f"no object named {name!r} in scene {scene.name!r} to mount the LiDAR "
                         f"on; mounts (rls_mount): {', '.join(mounts) or 'none'}")
    return obj


def add_lidar(scene, mounting, lob=None):
    """Add the LiDAR ``mounting`` (``core.scene.mounting.LidarMounting``) describes to
    ``scene``: its preset resolved (user presets too), on its mount or at its point,
    facing the InfraLOB (``lob``: its name, default the one marked) when asked. Returns
    the object. Nothing is added when anything is refused."""
    from .preset_catalog import resolve
    from .study import find_lob

    preset = resolve(mounting.preset)
    if mounting.mount is not None:
        position = mount_position(find_mount(scene, mounting.mount))
    else:
        position = mounting.at
    centre = None
    if mounting.face_region:
        centre = polygon_centroid(lob_polygon_world(find_lob(scene, lob)))
    return new_lidar(scene, mounting.name, preset.id, position,
                     mounting.euler(position, centre))


def lidar_rows(scene):
    """One dict per LiDAR of ``scene`` (sorted by name) at its current frame: name,
    device, world position, which way its +X looks (yaw counter-clockwise from world +X,
    pitch below the horizon, degrees), parent and output folder."""
    from .preset_catalog import entry

    rows = []
    for obj in lidar_objects(scene):
        s = lidar_props(obj)
        m = np.array(obj.matrix_world, dtype=np.float64)
        fwd = m[:3, 0] / (np.linalg.norm(m[:3, 0]) or 1.0)
        e = entry(s.preset_id)
        rows.append({
            "name": obj.name, "preset": s.preset_id,
            "device": e.name if e is not None else f"unknown preset {s.preset_id!r}",
            "position_m": [round(float(v), 4) for v in m[:3, 3]],
            "yaw_deg": round(math.degrees(math.atan2(fwd[1], fwd[0])), 3),
            "pitch_deg": round(math.degrees(math.asin(max(-1.0, min(1.0, -fwd[2])))), 3),
            "parent": obj.parent.name if obj.parent is not None else None,
            "output_dir": s.output_dir})
    return rows


def remove_lidars(scene, names):
    """Remove the LiDARs called ``names`` from the file, with their field-of-view
    outlines and preview points; every name is checked before anything is removed."""
    names = list(dict.fromkeys(names))
    objs = [find_lidar(scene, n) for n in names]
    for obj in objs:
        extras = [o for o in (fov_object(obj), preview_object(obj)) if o is not None]
        for o in extras + [obj]:
            data = o.data
            bpy.data.objects.remove(o)
            if data is not None and data.users == 0 and isinstance(data, bpy.types.Mesh):
                bpy.data.meshes.remove(data)
    return names

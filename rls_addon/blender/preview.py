"""Point previews in the viewport: a vertex-only mesh with per-point attributes."""

import bpy
import numpy as np

from ..core.points import transform_points, xyz

PREVIEW_PROPERTY = "rls_preview"
ATTRIBUTES = (("intensity", "FLOAT"), ("ring", "INT"), ("time", "FLOAT"),
              ("label", "INT"), ("instance", "INT"), ("ghost", "INT"))


def show_points(scene, sensor_obj, points, frame_space, sensor_to_world):
    """Create or replace the preview object of ``sensor_obj`` holding ``points``.

    The preview is in world coordinates (points in the sensor frame are moved there)
    and carries intensity, ring, time, label, instance and ghost as point attributes.
    """
    if frame_space == "sensor":
        points = transform_points(points, sensor_to_world)
    name = f"{sensor_obj.name} points"
    mesh = bpy.data.meshes.new(name)
    co = xyz(points).astype(np.float32)
    mesh.vertices.add(len(points))
    mesh.vertices.foreach_set("co", co.ravel())
    for field, kind in ATTRIBUTES:
        attr = mesh.attributes.new(field, kind, "POINT")
        values = points[field].astype(np.float32 if kind == "FLOAT" else np.int32)
        attr.data.foreach_set("value", values)
    mesh.update()
    obj = bpy.data.objects.get(name)
    if obj is not None and obj.get(PREVIEW_PROPERTY):
        old = obj.data
        obj.data = mesh
        if old.users == 0:
            bpy.data.meshes.remove(old)
    else:
        obj = bpy.data.objects.new(name, mesh)
        obj[PREVIEW_PROPERTY] = True
        scene.collection.objects.link(obj)
    obj.hide_render = True
    return obj

"""The field of view of a LiDAR drawn in the viewport, so a user can aim the sensor.

A wire-only mesh object parented to the LiDAR (marked ``rls_fov``, hidden from render,
never scanned) outlines the preset's angular extents at a chosen distance:

- a spinning sensor with a full turn: the upper and lower elevation cones as circles,
  joined by four meridians and with rays from the sensor;
- a pattern whose rays fill an ellipse (Livox rosettes): an elliptic cone through its
  horizontal and vertical FOV;
- anything else (MEMS rasters, wide Livox fields, custom patterns): a rectangular patch
  of the sphere between the azimuth and elevation limits, with rays to its corners.

Plain mesh data, so it works without a window (background mode) and in saved files.
"""

import math

import bpy
import numpy as np

from ..core.device.patterns.base import angles_from_directions, directions_from_angles
from ..core.device.families.spinning import spinning_elevations_offsets

FOV_PROPERTY = "rls_fov"
FULL_TURN_GAP = math.radians(10.0)
_EXTENT_CACHE = {}


def fov_extents(preset):
    """Angular extents of a preset in radians, as a dict:
    ``full_turn`` (bool), ``az`` (min, max), ``el`` (min, max), ``shape``
    ('turn', 'ellipse' or 'rect'). Cached per preset file."""
    key = (preset.id, preset.path, preset.family)
    if key in _EXTENT_CACHE:
        return _EXTENT_CACHE[key]
    if preset.family == "spinning" and "horizontal_fov_deg" not in preset.scan:
        el, _ = spinning_elevations_offsets(preset)
        out = {"full_turn": True, "az": (-math.pi, math.pi),
               "el": (math.radians(float(np.min(el))), math.radians(float(np.max(el)))),
               "shape": "turn"}
    else:
        d = preset.pattern(0).directions
        if len(d) > 200_000:
            d = d[:: len(d) // 200_000 + 1]
        az, el = angles_from_directions(d)
        s = np.sort(az)
        gaps = np.diff(np.r_[s, s[0] + 2 * math.pi])
        k = int(np.argmax(gaps))
        if gaps[k] < FULL_TURN_GAP:
            out = {"full_turn": True, "az": (-math.pi, math.pi), "shape": "turn"}
        else:
            start = s[(k + 1) % len(s)]  # the extent runs from after the largest gap ...
            span = 2 * math.pi - gaps[k]
            out = {"full_turn": False, "az": (float(start), float(start + span))}
        out["el"] = (float(el.min()), float(el.max()))
        if not out["full_turn"]:
            # an ellipse when the rays stay inside the ellipse through the extents
            # (Livox rosettes), else the rectangle (MEMS rasters, wide Livox fields)
            a = np.mod(az - out["az"][0], 2 * math.pi)
            half_a, half_e = max(span / 2, 1e-9), max((out["el"][1] - out["el"][0]) / 2, 1e-9)
            r2 = ((a - span / 2) / half_a) ** 2 + ((el - (out["el"][0] + half_e)) / half_e) ** 2
            out["shape"] = "ellipse" if np.quantile(r2, 0.999) <= 1.1 else "rect"
    _EXTENT_CACHE[key] = out
    return out


def _ring(az, el, length):
    return (directions_from_angles(az, el) * length).tolist()


def fov_wire(extents, length=3.0, steps=48):
    """(vertices, edges) of the FOV outline at ``length`` metres, in the sensor frame.
    Vertex 0 is the sensor origin."""
    verts = [(0.0, 0.0, 0.0)]
    edges = []

    def polyline(points, closed):
        first = len(verts)
        verts.extend(points)
        n = len(points)
        edges.extend((first + i, first + i + 1) for i in range(n - 1))
        if closed:
            edges.append((first + n - 1, first))
        return first

    def ray_to(index):
        edges.append((0, index))

    el0, el1 = extents["el"]
    if extents["shape"] == "turn":
        az = np.linspace(-math.pi, math.pi, steps, endpoint=False)
        lo = polyline(_ring(az, np.full(steps, el0), length), True)
        hi = polyline(_ring(az, np.full(steps, el1), length), True)
        for q in range(4):  # meridians and rays at front, left, back, right
            i = q * steps // 4
            polyline(_ring(np.full(9, az[i]), np.linspace(el0, el1, 9), length)[1:-1], False)
            edges.append((lo + i, len(verts) - 7))
            edges.append((len(verts) - 1, hi + i))
            ray_to(lo + i)
            ray_to(hi + i)
        return verts, edges
    a0, a1 = extents["az"]
    if extents["shape"] == "ellipse":
        t = np.linspace(0, 2 * math.pi, steps, endpoint=False)
        ac, ah = (a0 + a1) / 2, (a1 - a0) / 2
        ec, eh = (el0 + el1) / 2, (el1 - el0) / 2
        first = polyline(_ring(ac + ah * np.cos(t), ec + eh * np.sin(t), length), True)
        for q in range(4):
            ray_to(first + q * steps // 4)
        return verts, edges
    n = max(2, steps // 4)
    a = np.linspace(a0, a1, n)
    e = np.linspace(el0, el1, n)
    pts = (_ring(a, np.full(n, el1), length) + _ring(np.full(n, a1), e[::-1], length)[1:]
           + _ring(a[::-1], np.full(n, el0), length)[1:] + _ring(np.full(n, a0), e, length)[1:-1])
    first = polyline(pts, True)
    for c in (0, n - 1, 2 * n - 2, 3 * n - 3):  # the four corners
        ray_to(first + c)
    return verts, edges


def fov_object(lidar):
    """The FOV wire object of ``lidar`` or None."""
    for child in lidar.children:
        if child.get(FOV_PROPERTY):
            return child
    return None


def remove_fov(lidar):
    obj = fov_object(lidar)
    if obj is not None:
        mesh = obj.data
        bpy.data.objects.remove(obj)
        if mesh is not None and mesh.users == 0:
            bpy.data.meshes.remove(mesh)


def update_fov(lidar, preset, length):
    """Create or refresh the FOV wire of ``lidar`` for ``preset``; returns the object."""
    verts, edges = fov_wire(fov_extents(preset), length)
    obj = fov_object(lidar)
    if obj is None:
        mesh = bpy.data.meshes.new(f"{lidar.name} FOV")
        obj = bpy.data.objects.new(f"{lidar.name} FOV", mesh)
        obj[FOV_PROPERTY] = True
        colls = list(lidar.users_collection) or [bpy.context.scene.collection]
        colls[0].objects.link(obj)
        obj.parent = lidar
        obj.matrix_parent_inverse.identity()
        obj.display_type = "WIRE"
        obj.hide_render = True
        obj.hide_select = True
        obj.visible_shadow = False
    else:
        mesh = obj.data
        mesh.clear_geometry()
    mesh.from_pydata(verts, edges, [])
    mesh.update()
    obj["rls_fov_preset"] = preset.id
    obj["rls_fov_length"] = float(length)
    return obj

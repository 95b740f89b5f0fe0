"""The coverage map in the viewport: a grid mesh over the InfraLOB, a quad per cell
inside the region, its colour (``core.live.coverage.cells``: the density chart's
colours, white where no point fell) in a corner colour attribute that Material Preview
and Solid shading with Color: Attribute show. Solid shading's default (Color: Material)
shows a material's viewport colour, so each cell also has the material of its band
(``core.live.coverage.levels``: white for no return, then 16 bands of viridis): the map
reads in the default viewport too, in bands. Data, not drawing: tests read it as the
viewport shows it."""

import bpy
import numpy as np
from mathutils import Color

from ..core.live.coverage import MAP_LEVELS, cells, level_colours, levels

MAP_PROPERTY = "rls_coverage"
COLOR_ATTRIBUTE = "coverage"
MATERIAL = "RLS coverage"
LIFT_M = 0.03  # above the region's surface, under the points


def map_name(lob_name):
    return f"RLS coverage {lob_name}"


def _materials():
    """The map's materials, one per band of ``levels`` (``RLS coverage 00`` for no
    return, then 01..16): each shows the cell's own colour (its colour attribute,
    emitted) in Material Preview and its band's colour in Solid shading."""
    out = []
    for i, rgba in enumerate(level_colours(MAP_LEVELS)):
        name = f"{MATERIAL} {i:02d}"
        mat = bpy.data.materials.get(name) or _material(name)
        # (Blender's colour properties hold scene-linear values)
        mat.diffuse_color = (*Color(rgba[:3]).from_srgb_to_scene_linear(), 1.0)
        out.append(mat)
    return out


def _material(name):
    mat = bpy.data.materials.new(name)
    nt = mat.node_tree
    nt.nodes.clear()
    col = nt.nodes.new("ShaderNodeVertexColor")
    col.layer_name = COLOR_ATTRIBUTE
    emit = nt.nodes.new("ShaderNodeEmission")
    out = nt.nodes.new("ShaderNodeOutputMaterial")
    nt.links.new(col.outputs["Color"], emit.inputs["Color"])
    nt.links.new(emit.outputs["Emission"], out.inputs["Surface"])
    for i, node in enumerate((col, emit, out)):
        node.location = (i * 250 - 400, 0)
    return mat


def _grid_mesh(name, corners, z):
    """A quad per cell (its own four vertices, so each cell has one flat colour)."""
    (x0, y0), (x1, y1) = corners[:, 0].T, corners[:, 1].T
    m = len(corners)
    co = np.empty((m, 4, 3))
    co[:, :, 2] = z
    co[:, 0, :2] = np.stack([x0, y0], 1)
    co[:, 1, :2] = np.stack([x1, y0], 1)
    co[:, 2, :2] = np.stack([x1, y1], 1)
    co[:, 3, :2] = np.stack([x0, y1], 1)
    mesh = bpy.data.meshes.new(name)
    mesh.vertices.add(4 * m)
    mesh.attributes["position"].data.foreach_set("vector", co.astype(np.float32).ravel())
    mesh.loops.add(4 * m)
    mesh.loops.foreach_set("vertex_index", np.arange(4 * m, dtype=np.int32))
    mesh.polygons.add(m)
    mesh.polygons.foreach_set("loop_start", np.arange(0, 4 * m, 4, dtype=np.int32))
    mesh.update()
    mesh.color_attributes.new(COLOR_ATTRIBUTE, "BYTE_COLOR", "CORNER")  # sRGB, as drawn
    mesh.color_attributes.active_color_name = COLOR_ATTRIBUTE
    for mat in _materials():
        mesh.materials.append(mat)
    return mesh


def show_coverage(scene, lob, density):
    """Create or update the map of ``density`` (a ``DensityMap``) over ``lob``; the
    mesh is made again only when its cells change (region or cell size), else only
    its colours are written. Returns the map object."""
    corners, rgba = cells(density)
    name = map_name(lob.name)
    obj = bpy.data.objects.get(name)
    shape = (f"{density.values.shape}{density.origin_xy}{density.cell_m}{len(corners)}"
             f" {MAP_LEVELS} levels")
    if obj is None or not obj.get(MAP_PROPERTY) or obj.get("rls_cells") != shape:
        z = float(np.max([(lob.matrix_world @ v.co).z for v in lob.data.vertices])) + LIFT_M
        mesh = _grid_mesh(name, corners, z)
        if obj is None or not obj.get(MAP_PROPERTY):
            obj = bpy.data.objects.new(name, mesh)
            obj[MAP_PROPERTY] = True
            obj.hide_render = True
            scene.collection.objects.link(obj)
        else:
            old, obj.data = obj.data, mesh
            if old.users == 0:
                bpy.data.meshes.remove(old)
        obj["rls_cells"] = shape
    attr = obj.data.color_attributes[COLOR_ATTRIBUTE]
    attr.data.foreach_set("color_srgb", np.repeat(rgba, 4, axis=0).astype(np.float32).ravel())
    obj.data.polygons.foreach_set("material_index", levels(density))
    obj.data.update()
    return obj


def remove_coverage(lob_name):
    obj = bpy.data.objects.get(map_name(lob_name))
    if obj is not None and obj.get(MAP_PROPERTY):
        mesh = obj.data
        bpy.data.objects.remove(obj)
        if mesh.users == 0:
            bpy.data.meshes.remove(mesh)


def map_colours(obj):
    """(cells, 4) RGBA of a map object, a row per cell (what the viewport shows)."""
    attr = obj.data.color_attributes[COLOR_ATTRIBUTE]
    out = np.empty(len(attr.data) * 4, np.float32)
    attr.data.foreach_get("color_srgb", out)
    return out.reshape(-1, 4, 4)[:, 0]


def map_bands(obj):
    """(cells,) band of each cell of a map object and (bands, 4) the sRGB colours of
    its materials in Solid shading (what the default viewport shows)."""
    idx = np.empty(len(obj.data.polygons), np.int32)
    obj.data.polygons.foreach_get("material_index", idx)
    srgb = [(*Color(m.diffuse_color[:3]).from_scene_linear_to_srgb(), m.diffuse_color[3])
            for m in obj.data.materials]
    return idx, np.array(srgb, np.float64)

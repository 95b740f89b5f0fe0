"""Point previews in the viewport: a vertex-only mesh with per-point attributes."""

import bpy
import numpy as np

from ..core.points import transform_points, xyz

PREVIEW_PROPERTY = "rls_preview"
ATTRIBUTES = (("intensity", "FLOAT"), ("ring", "INT"), ("time", "FLOAT"),
              ("label", "INT"), ("instance", "INT"), ("ghost", "INT"))


def show_points(scene, sensor_obj, points, frame_space, sensor_to_world, color_by=None):
    """Create or replace the preview object of ``sensor_obj`` holding ``points``.

    The preview is in world coordinates (points in the sensor frame are moved there)
    and carries intensity, ring, time, label, instance and ghost as point attributes.
    ``color_by`` (an attribute name) shows it as points coloured by that attribute; by
    default a preview keeps the colouring it had.
    """
    if frame_space == "sensor":
        points = transform_points(points, sensor_to_world)
    name = f"{sensor_obj.name} points"
    mesh = bpy.data.meshes.new(name)
    co = xyz(points).astype(np.float32)
    mesh.vertices.add(len(points))
    # the position attribute takes the array as it is (0.04 ms for 80,000 points, where
    # vertices' "co" went point by point: 11.5 ms)
    if len(points):
        mesh.attributes["position"].data.foreach_set("vector", co.ravel())
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
    color_by = color_by or obj.get(COLOR_PROPERTY)
    if color_by in COLOR_ATTRIBUTES:
        color_preview(obj, color_by)
    return obj


# ---- colouring ---------------------------------------------------------------------

COLOR_ATTRIBUTES = ("intensity", "label", "time", "ring")
COLOR_PROPERTY = "rls_color_by"
POINTS_GROUP = "RLS Points"
POINTS_MODIFIER = "RLS Points"
POINT_RADIUS_M = 0.03
LABEL_SLOTS = 32  # label ids 0..31 get their own colour; the default table uses 0..17
_RAMP = ((0.0, (0.267, 0.005, 0.329)), (0.25, (0.229, 0.322, 0.546)),
         (0.5, (0.128, 0.567, 0.551)), (0.75, (0.369, 0.789, 0.383)),
         (1.0, (0.993, 0.906, 0.144)))  # viridis


def label_palette(n=LABEL_SLOTS):
    """(n, 3) distinct, stable RGB colours for label ids 0..n-1 (0, unlabeled, is grey)."""
    out = np.empty((n, 3))
    for i in range(n):
        h = (i * 0.618033988749895) % 1.0
        k = np.array([5.0, 3.0, 1.0])
        v, s = 0.95, 0.75
        kk = (k + h * 6) % 6
        out[i] = v - v * s * np.clip(np.minimum(kk, 4 - kk), 0, 1)
    out[0] = (0.5, 0.5, 0.5)
    return out


def points_node_group():
    """The shared geometry-nodes group: mesh vertices -> points with a material."""
    ng = bpy.data.node_groups.get(POINTS_GROUP)
    if ng is not None and ng.bl_idname == "GeometryNodeTree":
        return ng
    ng = bpy.data.node_groups.new(POINTS_GROUP, "GeometryNodeTree")
    ng.is_modifier = True
    face = ng.interface
    face.new_socket("Geometry", in_out="INPUT", socket_type="NodeSocketGeometry")
    face.new_socket("Material", in_out="INPUT", socket_type="NodeSocketMaterial")
    face.new_socket("Radius", in_out="INPUT", socket_type="NodeSocketFloat")
    face.new_socket("Geometry", in_out="OUTPUT", socket_type="NodeSocketGeometry")
    gi, go = ng.nodes.new("NodeGroupInput"), ng.nodes.new("NodeGroupOutput")
    to_points = ng.nodes.new("GeometryNodeMeshToPoints")
    set_mat = ng.nodes.new("GeometryNodeSetMaterial")
    ng.links.new(gi.outputs["Geometry"], to_points.inputs["Mesh"])
    ng.links.new(gi.outputs["Radius"], to_points.inputs["Radius"])
    ng.links.new(to_points.outputs["Points"], set_mat.inputs["Geometry"])
    ng.links.new(gi.outputs["Material"], set_mat.inputs["Material"])
    ng.links.new(set_mat.outputs["Geometry"], go.inputs["Geometry"])
    gi.location, to_points.location, set_mat.location, go.location = (-400, 0), (-200, 0), (0, 0), (200, 0)
    return ng


def _socket_id(ng, name):
    for item in ng.interface.items_tree:
        if getattr(item, "in_out", None) == "INPUT" and item.name == name:
            return item.identifier
    raise KeyError(name)


def attribute_range(mesh, attribute):
    """(lo, hi) the colour ramp spans for ``attribute`` of a preview mesh."""
    if attribute == "intensity":
        return 0.0, 1.0
    if attribute == "label":
        return 0.0, float(LABEL_SLOTS)
    attr = mesh.attributes.get(attribute)
    n = len(mesh.vertices)
    if attr is None or n == 0:
        return 0.0, 1.0
    values = np.empty(n, dtype=np.float32 if attr.data_type == "FLOAT" else np.int32)
    attr.data.foreach_get("value", values)
    hi = float(values.max())
    return 0.0, hi if hi > 0 else 1.0


def color_material(name, attribute, lo, hi):
    """A material that colours points by ``attribute``: Attribute node -> Map Range
    (lo..hi to 0..1) -> Color Ramp (viridis; constant label colours) -> Emission."""
    mat = bpy.data.materials.get(name) or bpy.data.materials.new(name)
    nt = mat.node_tree
    nt.nodes.clear()
    attr = nt.nodes.new("ShaderNodeAttribute")
    attr.attribute_type = "GEOMETRY"
    attr.attribute_name = attribute
    remap = nt.nodes.new("ShaderNodeMapRange")
    remap.clamp = True
    remap.inputs["From Min"].default_value = lo
    remap.inputs["From Max"].default_value = hi
    ramp = nt.nodes.new("ShaderNodeValToRGB")
    cr = ramp.color_ramp
    if attribute == "label":
        cr.interpolation = "CONSTANT"
        colors = label_palette()
        stops = [(i / LABEL_SLOTS, colors[i]) for i in range(LABEL_SLOTS)]
    else:
        cr.interpolation = "LINEAR"
        stops = _RAMP
    while len(cr.elements) > 1:
        cr.elements.remove(cr.elements[-1])
    cr.elements[0].position = stops[0][0]
    cr.elements[0].color = (*stops[0][1], 1.0)
    for pos, rgb in stops[1:]:
        cr.elements.new(pos).color = (*rgb, 1.0)
    emit = nt.nodes.new("ShaderNodeEmission")
    out = nt.nodes.new("ShaderNodeOutputMaterial")
    nt.links.new(attr.outputs["Fac"], remap.inputs["Value"])
    nt.links.new(remap.outputs["Result"], ramp.inputs["Fac"])
    nt.links.new(ramp.outputs["Color"], emit.inputs["Color"])
    nt.links.new(emit.outputs["Emission"], out.inputs["Surface"])
    for i, node in enumerate((attr, remap, ramp, emit, out)):
        node.location = (i * 250 - 600, 0)
    mat[COLOR_PROPERTY] = attribute
    mat.diffuse_color = (*stops[len(stops) // 2][1], 1.0)
    return mat


def color_preview(obj, attribute, radius=POINT_RADIUS_M):
    """Show preview ``obj`` as points coloured by ``attribute`` (intensity, label, time
    or ring): a geometry-nodes modifier turns the vertices into points and gives them a
    material reading the attribute. Returns the material."""
    if attribute not in COLOR_ATTRIBUTES:
        raise ValueError(f"cannot colour by {attribute!r}; choose one of {', '.join(COLOR_ATTRIBUTES)}")
    lo, hi = attribute_range(obj.data, attribute)
    mat = color_material(f"{obj.name} colors", attribute, lo, hi)
    ng = points_node_group()
    mod = obj.modifiers.get(POINTS_MODIFIER)
    if mod is None or mod.type != "NODES":
        mod = obj.modifiers.new(POINTS_MODIFIER, "NODES")
    mod.node_group = ng
    mod[_socket_id(ng, "Material")] = mat
    mod[_socket_id(ng, "Radius")] = float(radius)
    if not obj.data.materials:
        obj.data.materials.append(mat)
    else:
        obj.data.materials[0] = mat
    obj[COLOR_PROPERTY] = attribute
    obj.update_tag()
    return mat


def preview_object(sensor_obj):
    """The preview object of a LiDAR, or None."""
    obj = bpy.data.objects.get(f"{sensor_obj.name} points")
    return obj if obj is not None and obj.get(PREVIEW_PROPERTY) else None


def preview_world_points(obj):
    """(N, 3) world xy z and (N,) labels of a preview object's points."""
    mesh = obj.data
    n = len(mesh.vertices)
    co = np.empty(n * 3, dtype=np.float32)
    if n:
        mesh.attributes["position"].data.foreach_get("vector", co)
    co = co.reshape(-1, 3).astype(np.float64)
    m = np.array(obj.matrix_world, dtype=np.float64)
    co = co @ m[:3, :3].T + m[:3, 3]
    labels = np.zeros(n, dtype=np.int32)
    attr = mesh.attributes.get("label")
    if attr is not None and n:
        attr.data.foreach_get("value", labels)
    return co, labels

"""A placement study's answer in the scene (``core.study.answer`` says what): in an
"RLS Study" collection, a small marker per candidate pointing where it looks and
coloured by the chosen score, and the best set of each k as LiDAR objects ready to
scan; the charts as images packed into the .blend; the table in ``Scene.rls_study``.
A new study replaces the previous answer (the objects of its collection, its images
and its table). Everything is made in one go after the study finished, so a study
stopped before leaves nothing of itself; a failure while making it removes what it
had made."""

import math

import bpy

from ..core.study.answer import (
    band_colours,
    best_sets,
    candidate_scores,
    score_bands,
    score_colours,
    score_range_text,
    table_rows,
)
from .images import image_from_png
from .lidars import new_lidar
from .sensor import lidar_props

COLLECTION = "RLS Study"
STUDY_PROPERTY = "rls_study"          # on every object and image a study makes
MARKER_MESH = "RLS Study marker"
MARKER_MATERIAL = "RLS Study marker"
MARKER_LENGTH_M = 0.8
CHART_PREFIX = "RLS Study "


def _marker_mesh():
    """A small pyramid along +X (the sensor's forward), shared by every marker."""
    mesh = bpy.data.meshes.get(MARKER_MESH)
    if mesh is not None:
        return mesh
    h, w = MARKER_LENGTH_M, MARKER_LENGTH_M * 0.3
    mesh = bpy.data.meshes.new(MARKER_MESH)
    mesh.from_pydata([(h, 0, 0), (0, -w, -w), (0, w, -w), (0, w, w), (0, -w, w)], [],
                     [(0, 1, 2), (0, 2, 3), (0, 3, 4), (0, 4, 1), (4, 3, 2, 1)])
    mesh.update()
    mesh.materials.append(_marker_material())
    return mesh


def _marker_material(name=MARKER_MATERIAL):
    """Emission of the object's colour (Object Info), so each marker shows its own in
    Material Preview; the band materials (``_band_materials``) are the same with their
    band's viewport colour, which Solid shading shows."""
    mat = bpy.data.materials.get(name)
    if mat is not None:
        return mat
    mat = bpy.data.materials.new(name)
    nt = mat.node_tree
    nt.nodes.clear()
    info = nt.nodes.new("ShaderNodeObjectInfo")
    emit = nt.nodes.new("ShaderNodeEmission")
    out = nt.nodes.new("ShaderNodeOutputMaterial")
    nt.links.new(info.outputs["Color"], emit.inputs["Color"])
    nt.links.new(emit.outputs["Emission"], out.inputs["Surface"])
    for i, node in enumerate((info, emit, out)):
        node.location = (i * 250 - 400, 0)
    return mat


def _band_materials():
    """One marker material per band of ``score_bands`` (``RLS Study marker 00`` for no
    value, then 01..16), each with its band's colour as its viewport colour."""
    from mathutils import Color

    out = []
    for i, rgba in enumerate(band_colours()):
        mat = _marker_material(f"{MARKER_MATERIAL} {i:02d}")
        # (Blender's colour properties hold scene-linear values)
        mat.diffuse_color = (*Color(rgba[:3]).from_srgb_to_scene_linear(), 1.0)
        out.append(mat)
    return out


def clear_answer(scene):
    """Remove the previous study's collection (with its objects), charts and table.
    Objects a user put into the collection are kept, linked to the scene's own."""
    coll = bpy.data.collections.get(COLLECTION)
    if coll is not None:
        for child in list(coll.children_recursive) + [coll]:
            for obj in list(child.objects):
                if obj.get(STUDY_PROPERTY):
                    bpy.data.objects.remove(obj)
                elif len(obj.users_collection) == 1:
                    scene.collection.objects.link(obj)
        for child in list(coll.children_recursive):
            bpy.data.collections.remove(child)
        bpy.data.collections.remove(coll)
    for img in [i for i in bpy.data.images if i.get(STUDY_PROPERTY)]:
        bpy.data.images.remove(img)
    props = scene.rls_study
    props.rows.clear()
    props.row_index = 0
    props.has_result = False


def _child(parent, name):
    coll = bpy.data.collections.new(name)
    parent.children.link(coll)
    return coll


def _markers(coll, result, scores):
    from mathutils import Matrix

    mesh = _marker_mesh()
    out = []
    for c in result.candidates:
        obj = bpy.data.objects.new(f"Study: {c.name}", mesh)
        # a Matrix of the rows: a nested list given to matrix_world is read column by
        # column (every marker stood at the origin, turned the inverse way)
        obj.matrix_world = Matrix([[float(v) for v in row] for row in c.pose])
        obj[STUDY_PROPERTY] = True
        obj["rls_candidate"] = c.index
        for score, values in scores.items():
            if math.isfinite(values[c.index]):
                obj[f"rls_{score}"] = float(values[c.index])
        obj.hide_render = True
        coll.objects.link(obj)
        out.append(obj)
    return out


def _best_lidars(scene, parent, result):
    cfg = result.config
    out = {}
    for k, members in best_sets(result).items():
        coll = _child(parent, f"{COLLECTION} best k={k}")
        for c in members:
            obj = new_lidar(scene, f"k{k} {c.name}", result.device["id"], c.position,
                            tuple(math.radians(a) for a in (c.roll_deg, c.pitch_deg, c.yaw_deg)),
                            collection=coll, show_fov=False, exact_name=False)
            obj[STUDY_PROPERTY] = True
            obj["rls_study_k"] = k
            s = lidar_props(obj)
            s.noise, s.dropout, s.seed = bool(cfg.noise), bool(cfg.dropout), int(cfg.scan_seed)
            if cfg.rotation_hz is not None:
                s.use_rotation_hz, s.rotation_hz = True, float(cfg.rotation_hz)
            if cfg.lidar_mode:
                s.lidar_mode = cfg.lidar_mode
            out.setdefault(k, []).append(obj)
    return out


def _fill_table(props, result):
    for r in table_rows(result):
        row = props.rows.add()
        row.k, row.sensors, row.points = r.k, r.sensors, r.points
        row.members = " ".join(str(i) for i in r.members)
        row.infra_d, row.infra_nuc = r.infra_d, r.infra_nuc
        row.visibility, row.ap = r.visibility, r.ap
        row.pareto, row.best = r.pareto, r.best


def show_answer(scene, result, charts):
    """Make the study's answer in ``scene`` (replacing the previous one); ``charts``:
    {file name: PNG bytes} (``report.charts_png``). Returns {"markers": [...],
    "lidars": {k: [...]}, "images": [...]}."""
    clear_answer(scene)
    made = {"markers": [], "lidars": {}, "images": []}
    try:
        root = bpy.data.collections.new(COLLECTION)
        scene.collection.children.link(root)
        scores = candidate_scores(result)
        made["markers"] = _markers(_child(root, f"{COLLECTION} candidates"), result, scores)
        made["lidars"] = _best_lidars(scene, root, result)
        for name, png in sorted(charts.items()):
            made["images"].append(image_from_png(CHART_PREFIX + name, png, tag=STUDY_PROPERTY))
        props = scene.rls_study
        _fill_table(props, result)
        if props.color_by not in scores:
            props.color_by = "infra_d"
        color_markers(scene, props.color_by)
        pareto = bpy.data.images.get(CHART_PREFIX + "pareto.png")
        props.chart = pareto or (made["images"][0] if made["images"] else None)
        props.has_result = True
    except BaseException:
        clear_answer(scene)
        raise
    return made


def markers(scene):
    """The study's candidate markers in ``scene``, by candidate index."""
    coll = bpy.data.collections.get(f"{COLLECTION} candidates")
    if coll is None:
        return []
    return sorted((o for o in coll.objects if o.get(STUDY_PROPERTY)),
                  key=lambda o: o["rls_candidate"])


def color_markers(scene, score):
    """Colour the markers by ``score`` (a ``STUDY_SCORES`` id) and say what the colours
    span in ``Scene.rls_study.color_range``."""
    objs = markers(scene)
    values = [o.get(f"rls_{score}", math.nan) for o in objs]
    bands = _band_materials() if objs else []
    for obj, rgba, band in zip(objs, score_colours(values, score), score_bands(values, score)):
        obj.color = tuple(float(v) for v in rgba)
        # its own material (slot linked to the object, the mesh is shared): its band's
        slot = obj.material_slots[0]
        slot.link = "OBJECT"
        slot.material = bands[band]
    scene.rls_study.color_range = score_range_text(values, score) if objs else ""

"""Scanning a Blender scene: extraction + motion sampling + BVHTree + the core engine."""

from dataclasses import replace

import bpy
import numpy as np

from ..core.engine import PreparedScene, RigidBodies, TimedScene, resolve_range, scan_frame
from ..core.motion import Track
from .bvh_caster import BVHCaster
from .extract import (MeshReader, instance_key, object_table, read_instances, read_mesh,
                      world_geometry)
from .motion import SweepClock, deformation, may_move, sample_sweep, substep_count
from .sensor import scan_inputs, sensor_pose

MOVER_MARGIN_M = 10.0  # objects this far beyond the range at the sweep start may drive in
# Once a lidar moves between frames, its static scene is prepared this share of its range
# farther out and kept while the lidar stays inside: a driving lidar's frames share one
# built structure instead of one per frame.
DRIVING_SLACK = 0.25


class ScanSession:
    """Scans several frames and sensors. Meshes are read once while unchanged
    (``extract.MeshReader``); static geometry is built into a ray-casting structure
    once and reused while it is unchanged (the same meshes, matrices, materials and
    labels; else its digest decides); each rigidly moving object's own structure is
    reused likewise; deforming objects are rebuilt per sub-step."""

    def __init__(self, caster_factory=BVHCaster):
        self.caster_factory = caster_factory
        self._prepared = {}
        self._bodies = {}
        self.builds = 0
        self.meshes = MeshReader()
        self._anchors = {}  # lidar name -> (centre, reach, range) its scene is prepared for

    def _cached(self, store, key, make):
        item = store.get(key)
        if item is None:
            if len(store) >= 16:  # bounded: a moving sensor keeps seeing new geometry
                store.pop(next(iter(store)))
            item = store[key] = make()
            self.builds += 1
        return item

    def prepared(self, geometry, centre, reach, key=None):
        """The ``PreparedScene`` of ``geometry`` (or of ``geometry()``, a function that
        builds it, when ``key`` identifies it without its digest)."""
        if key is None:
            geometry = geometry() if callable(geometry) else geometry
            key = geometry.fingerprint()
        key = (key, tuple(np.round(centre, 9)), reach)
        return self._cached(self._prepared, key, lambda: PreparedScene(
            geometry() if callable(geometry) else geometry, centre, reach, self.caster_factory))

    @staticmethod
    def _static_key(instances, objects, materials, select):
        """A key equal for equal static geometry, from what was read (no digest of the
        triangles): each selected instance's mesh id, matrix, materials and label, and
        the object and material tables. None when a mesh has no id."""
        parts = []
        for k in sorted(select):
            inst = instances[k]
            if not inst.mesh_id:
                return None
            parts.append((inst.key, inst.label, inst.mesh_id, inst.matrix.tobytes(),
                          inst.slot_map.tobytes()))
        return ("instances", tuple(parts), repr((objects, materials)))

    def _anchor(self, name, centre, rmax):
        """(centre, reach) to prepare a lidar's static scene for: where it stands, with
        its range, until it moves; then around where it moved to, reaching
        ``DRIVING_SLACK`` of its range farther, kept while it stays inside (with room
        for ``MOVER_MARGIN_M`` of travel within a sweep)."""
        got = self._anchors.get(name)
        moved = False
        if got is not None and got[2] == rmax:
            anchor, reach, _ = got
            gap = float(np.linalg.norm(centre - anchor))
            if gap == 0.0 or gap + rmax + MOVER_MARGIN_M <= reach:
                return anchor, reach
            moved = True
        reach = rmax * (1.0 + DRIVING_SLACK) + MOVER_MARGIN_M if moved else rmax
        self._anchors[name] = (centre.copy(), reach, rmax)
        return centre, reach

    def scan(self, depsgraph, obj, frame, settings=None, context=None):
        """Scan one frame of LiDAR ``obj`` in ``depsgraph`` (already at ``frame``).

        ``context`` (default ``bpy.context``) is used to sample motion over the sweep;
        in snapshot mode the scene is taken as it is at ``frame``.
        Returns (ScanResult, info dict for the sidecar)."""
        context = context or bpy.context
        preset, obj_settings = scan_inputs(obj)
        settings = settings or obj_settings
        pose = sensor_pose(obj.evaluated_get(depsgraph))
        rmin, rmax = resolve_range(preset, settings)
        centre = pose[:3, 3]
        anchor, reach = self._anchor(obj.name, centre, rmax)
        instances, materials, stats = read_instances(
            depsgraph, centre=anchor, max_range=reach + MOVER_MARGIN_M, exclude={obj.name},
            reader=self.meshes)
        objects = object_table(instances)
        motion = {"rigid": [], "deforming": [], "samples": 1, "substeps": {}}
        moving, track = [], None
        static_sel = set(range(len(instances)))
        if settings.motion != "snapshot":
            moving, track, static_sel, motion = self._motion(
                context, frame, preset, settings, obj, instances, objects, materials, rmax)
        if track is not None:
            sweep = track.matrices[:, :3, 3]
            if np.linalg.norm(sweep - anchor, axis=1).max() + rmax > reach:
                # The sweep leaves the anchored scene: one around this sweep alone.
                anchor = centre
                reach = rmax + float(np.linalg.norm(sweep - centre, axis=1).max())
        # Joined (and digested) only when the session has not built it before.
        scene = self.prepared(
            lambda: world_geometry(instances, objects, materials, select=static_sel), anchor,
            reach, self._static_key(instances, objects, materials, static_sel))
        result = scan_frame(scene, preset.pattern(frame), pose, preset, settings, frame=frame,
                            sensor=obj.name, sensor_track=track, moving=moving)
        labels = {str(o.instance): {"object": o.name, "label": o.label} for o in objects}
        info = {
            "device": {"id": preset.id, "name": preset.name, "source": preset.source},
            "sensor": obj.name,
            "frame": frame,
            "frame_space": settings.frame_space,
            "sensor_to_world": pose.tolist(),
            "seed": settings.seed,
            "effects": {"noise": settings.noise, "dropout": settings.dropout,
                        "range_m": [rmin, rmax],
                        "noise_sigma_m": preset.range.noise_sigma_m if settings.noise else 0.0,
                        "motion": settings.motion, "substeps": settings.substeps,
                        "ghosting": settings.ghosting},
            "motion": motion,
            "labels": labels,
            "backend": scene.backend,
            "rays": result.rays,
            "points": int(len(result.points)),
            "triangles_cast": result.triangles,
            "objects_read": stats["objects"],
            "objects_culled_by_range": stats["culled_by_range"],
            "ghosts": result.stats.get("ghosts", 0),
            "static_cast_reused": bool(result.stats.get("static_cast_reused", False)),
            "warnings": result.warnings,
        }
        return result, info

    def _motion(self, context, frame, preset, settings, obj, instances, objects, materials,
                rmax):
        """Sample the sweep; return (moving bodies, sensor Track or None, indices of
        static instances, a summary for the sidecar)."""
        scene = context.scene
        cand = []
        for k, inst in enumerate(instances):
            ob = scene.objects.get(inst.source)
            par = scene.objects.get(inst.parent) if inst.parent else None
            if (ob is not None and may_move(ob)) or (par is not None and may_move(par)):
                cand.append(k)
        sensor_moves = may_move(obj)
        summary = {"rigid": [], "deforming": [], "samples": 1, "substeps": {}}
        if not cand and not sensor_moves:
            return [], None, set(range(len(instances))), summary
        clock = SweepClock(scene, frame, preset.period)
        try:
            times, mats, verts, sensor = sample_sweep(context, clock, instances, cand, obj,
                                                      sensor_moves)
            summary["samples"] = len(times)
            static_sel = set(range(len(instances)))
            bodies, rigid = [], []
            tol = settings.motion_tolerance_m or preset.range.noise_sigma_m or 0.01
            for k in cand:
                inst = instances[k]
                m = mats[k]
                moved = bool(np.abs(m - m[0]).max() > 1e-12)
                deform = deformation(verts[k]) if k in verts else 0.0
                if deform > 1e-9:
                    corners = np.array([inst.vertices.min(0), inst.vertices.max(0)])
                    travel = Track(times, m).max_displacement(corners)
                    n = substep_count(deform + travel, tol, settings.substeps)
                    bodies += self._substeps(context, clock, inst, k, objects, materials, n)
                    summary["deforming"].append(inst.key)
                    summary["substeps"][inst.key] = n
                    static_sel.discard(k)
                elif moved:
                    local = world_geometry(instances, objects, materials, select={k}, local=True)
                    rigid.append((inst.key, local, Track(times, m)))
                    summary["rigid"].append(inst.key)
                    static_sel.discard(k)
            if rigid:
                key = tuple((name, local.fingerprint()) for name, local, _ in rigid)
                group = self._cached(self._bodies, key, lambda: RigidBodies(
                    [(local, tr) for _, local, tr in rigid], self.caster_factory))
                group.tracks = [tr for _, _, tr in rigid]  # this sweep's motion
                bodies.append(group)
            track = None
            if sensor is not None and np.abs(sensor - sensor[0]).max() > 1e-12:
                track = Track(times, sensor)
            summary["sensor_moves"] = track is not None
        finally:
            clock.restore()
        return bodies, track, static_sel, summary

    def _substeps(self, context, clock, inst, k, objects, materials, n):
        """TimedScenes of a deforming instance at the middle of each of n sub-sweeps."""
        out = []
        step = clock.period / n
        for j in range(n):
            clock.set((j + 0.5) * step)
            dg = context.evaluated_depsgraph_get()
            for i in dg.object_instances:
                if instance_key(i) == inst.key:
                    co, tri, mat = read_mesh(i.object)
                    m = np.array(i.matrix_world, dtype=np.float64)
                    snap = replace(inst, vertices=co, triangles=tri,
                                   materials=inst.material_indices(mat), matrix=m)
                    geom = world_geometry([snap], [objects[k]], materials)
                    centre = m[:3, 3]
                    scene = PreparedScene(geom, centre, np.inf, self.caster_factory)
                    self.builds += 1
                    t1 = (j + 1) * step if j < n - 1 else np.inf
                    out.append(TimedScene(scene, j * step if j else -np.inf, t1))
                    break
        return out


def session_for(backend="auto"):
    """(ScanSession on the named ray-casting backend, notice or None): the notice says
    when Embree was asked for but BVHTree is used (never silently)."""
    from ..core.errors import SceneError
    from .backends import caster_factory

    try:
        factory, notice = caster_factory(backend)
    except ValueError as exc:
        raise SceneError(str(exc)) from None
    return ScanSession(factory), notice


def scan_lidar(depsgraph, obj, frame, caster_factory=BVHCaster, settings=None, context=None):
    """Scan one frame of one LiDAR without reuse across calls (see ``ScanSession``)."""
    return ScanSession(caster_factory).scan(depsgraph, obj, frame, settings, context)


def save_scan(result, info, out_dir, template, fmt, scene_name, overwrite=False, fields=None):
    """Write the points (``fields``: which point fields, default all) and their JSON
    sidecar; return the cloud's path."""
    from ..core.io import output_path, write_cloud, write_sidecar
    from ..core.io.fields import resolve_fields
    from ..version import VERSION

    fields = resolve_fields(None if fields is None else list(fields))
    path = output_path(out_dir, template, scene=scene_name, sensor=info["sensor"],
                       frame=info["frame"], fmt=fmt)
    write_cloud(path, result.points, fmt=fmt, fields=fields, overwrite=overwrite)
    write_sidecar(path, dict(info, format=fmt, fields=list(fields), software=f"rls {VERSION}"),
                  overwrite=overwrite)
    return path

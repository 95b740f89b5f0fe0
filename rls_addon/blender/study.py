"""A Blender scene as a placement study's scene (``core.scene.source.StudyScene``): its
InfraLOB, its mounts and its static geometry. The study itself runs in the core."""

import os

import bpy

from ..core.study.loop import run_study as core_run_study
from ..core.errors import RegionError, SceneError
from ..core.scene.instances import object_table, world_geometry
from ..core.scene.source import SceneRead
from .extract import read_instances
from .read_rules import read_warnings
from .region import is_lob, lob_polygon_world
from .source import traffic_span
from .scenes.build import is_mount, mount_position


def find_lob(scene, name=None):
    """The InfraLOB object: ``name``, else the single object marked ``rls_infralob``."""
    if name:
        obj = scene.objects.get(name)
        if obj is None:
            raise RegionError(f"no object named {name!r} in scene {scene.name!r}")
        return obj
    marked = sorted((o for o in scene.objects if is_lob(o)), key=lambda o: o.name)
    if not marked:
        raise RegionError(f"scene {scene.name!r} has no InfraLOB: mark a flat mesh with the "
                          "custom property rls_infralob = True, or pass --lob NAME")
    if len(marked) > 1:
        raise RegionError("several InfraLOB objects (" + ", ".join(o.name for o in marked)
                          + "); choose one with --lob NAME")
    return marked[0]


def find_mounts(scene, names=()):
    if names:
        out = []
        for n in names:
            obj = scene.objects.get(n)
            if obj is None:
                raise SceneError(f"no mount object named {n!r} in scene {scene.name!r}")
            out.append(obj)
        return out
    return sorted((o for o in scene.objects if is_mount(o)), key=lambda o: o.name)


class BlenderStudyScene:
    """``scene`` (a ``bpy.types.Scene``) for ``core.study.loop.run_study``."""

    def __init__(self, scene):
        self.scene = scene
        self.name = scene.name
        self.file = os.path.basename(bpy.data.filepath)  # '' for an unsaved file
        self.warnings = []  # what its last static read could not read (the study says it)

    def current_frame(self):
        return self.scene.frame_current

    def set_frame(self, frame):
        self.scene.frame_set(int(frame))

    def region(self, name):
        return lob_polygon_world(find_lob(self.scene, name))

    def mounts(self, names):
        return [(obj.name, mount_position(obj)) for obj in find_mounts(self.scene, names)]

    def static_geometry(self, hidden_labels):
        instances, materials, stats = read_instances(bpy.context.evaluated_depsgraph_get())
        self.warnings = read_warnings(stats)
        hidden = sorted(i.key for i in instances if i.label in hidden_labels)
        static = [i for i in instances if i.label not in hidden_labels]
        return world_geometry(static, object_table(static), materials), hidden

    def traffic_span(self):
        return traffic_span(self.scene)

    def traffic(self, frames, labels):
        out = {}
        for f in frames:
            self.set_frame(f)
            instances, materials, stats = read_instances(bpy.context.evaluated_depsgraph_get())
            out[int(f)] = SceneRead([i for i in instances if i.label in labels], materials, stats)
        return out


def run_study(scene, cfg, progress=None, scan_all=None):
    """``core.study.loop.run_study`` on a Blender scene (``scan_all``: see there)."""
    return core_run_study(BlenderStudyScene(scene), cfg, progress, scan_all=scan_all)

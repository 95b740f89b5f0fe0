"""A Blender scene as the core's scene source (``core.source.SceneSource``): the
depsgraph read at the current frame, motion read at sub-frame times."""

from dataclasses import replace

import numpy as np

from ..core.source import Mobility, SceneRead
from .extract import MeshReader, instance_key, read_instances, read_mesh
from .motion import SweepClock, may_deform, may_move, read_state


class BlenderScene:
    """``scene`` (a ``bpy.types.Scene``) in ``context`` (default ``bpy.context``). One
    source serves a whole run: its ``MeshReader`` reads a mesh that does not change
    between frames once."""

    def __init__(self, scene, context=None):
        import bpy

        self.scene = scene
        self.context = context or bpy.context
        self.name = scene.name
        self.fps = scene.render.fps / scene.render.fps_base
        self.frame_start = scene.frame_start
        self.meshes = MeshReader()

    def depsgraph(self):
        return self.context.evaluated_depsgraph_get()

    def current_frame(self):
        return self.scene.frame_current

    def set_frame(self, frame):
        self.scene.frame_set(int(frame))

    def sensor_pose(self, sensor):
        from ..core.errors import SceneError
        from .sensor import is_lidar

        obj = self.scene.objects.get(sensor)
        if obj is None or not is_lidar(obj):
            raise SceneError(f"LiDAR '{sensor}' is not in scene '{self.name}' (removed or "
                             "renamed while scanning?)")
        return np.array(obj.evaluated_get(self.depsgraph()).matrix_world, dtype=np.float64)

    def sensor_may_move(self, sensor):
        obj = self.scene.objects.get(sensor)
        return obj is not None and may_move(obj)

    def read(self, centre, max_range, exclude):
        instances, materials, stats = read_instances(
            self.depsgraph(), centre=centre, max_range=max_range, exclude=set(exclude),
            reader=self.meshes)
        return SceneRead(instances, materials, stats)

    def mobility(self, instances, sensor):
        objects = self.scene.objects
        out = Mobility(sensor_moves=may_move(objects[sensor]))
        for k, inst in enumerate(instances):
            ob = objects.get(inst.source)
            par = objects.get(inst.parent) if inst.parent else None
            if (ob is not None and may_move(ob)) or (par is not None and may_move(par)):
                out.candidates.append(k)
                if ob is not None and may_deform(ob):
                    out.deformable.add(inst.key)
        return out

    def sweep(self, frame, period):
        return BlenderSweep(self, frame, period)


class BlenderSweep:
    """The scene at sub-frame times over one sweep (``core.source.Sweep``)."""

    def __init__(self, source, frame, period):
        self.source = source
        self.clock = SweepClock(source.scene, frame, period)

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.clock.restore()

    def state(self, t, keys, deform_keys, sensor):
        self.clock.set(t)
        return read_state(self.source.depsgraph(), keys, deform_keys, sensor)

    def instance_at(self, t, instance):
        self.clock.set(t)
        for i in self.source.depsgraph().object_instances:
            if instance_key(i) == instance.key:
                co, tri, mat = read_mesh(i.object)
                return replace(instance, vertices=co, triangles=tri,
                               materials=instance.material_indices(mat),
                               matrix=np.array(i.matrix_world, dtype=np.float64))
        return None

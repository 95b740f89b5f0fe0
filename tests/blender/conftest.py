"""Blender tier: tests against the real ``bpy`` module (Blender built as a module).

The extension is registered once for the session from the source tree; each test
starts from an empty scene.
"""

import numpy as np
import pytest

bpy = pytest.importorskip("bpy")


@pytest.fixture(scope="session")
def addon():
    import rls_addon

    rls_addon.register()
    yield rls_addon
    rls_addon.unregister()


@pytest.fixture
def scene(addon):
    bpy.ops.wm.read_factory_settings(use_empty=True)
    if not hasattr(bpy.types.Object, "rls_lidar"):  # factory reset unregistered us
        addon.register()
    return bpy.context.scene


def mesh_object(name, verts, faces, collection=None, scene=None):
    scene = scene or bpy.context.scene
    mesh = bpy.data.meshes.new(name)
    mesh.from_pydata([tuple(map(float, v)) for v in verts], [], faces)
    mesh.update()
    obj = bpy.data.objects.new(name, mesh)
    (collection or scene.collection).objects.link(obj)
    return obj


def add_lidar(name="LiDAR", location=(0, 0, 0), rotation=(0, 0, 0), preset="generic_uniform32"):
    obj = bpy.data.objects.new(name, None)
    obj.location = location
    obj.rotation_euler = rotation
    bpy.context.scene.collection.objects.link(obj)
    obj.rls_lidar.is_lidar = True
    obj.rls_lidar.preset = preset
    obj.rls_lidar.noise = False
    obj.rls_lidar.dropout = False
    return obj


def ground(size=60.0, z=0.0, name="Ground"):
    return mesh_object(name, [(-size, -size, z), (size, -size, z), (size, size, z),
                              (-size, size, z)], [(0, 1, 2, 3)])


def scan(obj, frame=None):
    from rls_addon.blender.scan import scan_lidar

    return scan_lidar(obj, frame, backend="bvhtree")


def xyz(points):
    return np.stack([points["x"], points["y"], points["z"]], axis=1)

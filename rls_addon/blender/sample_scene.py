"""A small procedural street scene, built with ``bpy.data`` only (no operators), so it
runs the same in the UI, ``blender -b`` and the ``bpy`` module.

Labels come from collection names (Road, Sidewalk, Buildings, Poles, Vehicles); the
region of interest is a flat rectangle marked ``rls_infralob``.
"""

import bpy
import numpy as np

BOX_FACES = [(0, 1, 2, 3), (4, 7, 6, 5), (0, 4, 5, 1), (1, 5, 6, 2), (2, 6, 7, 3), (3, 7, 4, 0)]


def _collection(scene, name):
    coll = bpy.data.collections.get(name) or bpy.data.collections.new(name)
    if coll.name not in scene.collection.children:
        scene.collection.children.link(coll)
    return coll


def _material(name, rgb, roughness=0.5, metallic=0.0, reflectivity=None):
    mat = bpy.data.materials.get(name) or bpy.data.materials.new(name)
    mat.diffuse_color = (*rgb, 1.0)
    mat.roughness = roughness
    mat.metallic = metallic
    if reflectivity is not None:
        mat["rls_reflectivity"] = reflectivity
    return mat


def _mesh_object(coll, name, verts, faces, material):
    mesh = bpy.data.meshes.new(name)
    mesh.from_pydata([tuple(map(float, v)) for v in verts], [], faces)
    mesh.update()
    mesh.materials.append(material)
    obj = bpy.data.objects.new(name, mesh)
    coll.objects.link(obj)
    return obj


def box(coll, name, lo, hi, material):
    (x0, y0, z0), (x1, y1, z1) = lo, hi
    verts = [(x0, y0, z0), (x1, y0, z0), (x1, y1, z0), (x0, y1, z0),
             (x0, y0, z1), (x1, y0, z1), (x1, y1, z1), (x0, y1, z1)]
    return _mesh_object(coll, name, verts, BOX_FACES, material)


def cylinder(coll, name, centre, radius, height, material, segments=16):
    a = np.linspace(0, 2 * np.pi, segments, endpoint=False)
    cx, cy, cz = centre
    ring = [(cx + radius * np.cos(t), cy + radius * np.sin(t)) for t in a]
    verts = [(x, y, cz) for x, y in ring] + [(x, y, cz + height) for x, y in ring]
    n = segments
    faces = [(i, (i + 1) % n, (i + 1) % n + n, i + n) for i in range(n)]
    faces += [tuple(range(n - 1, -1, -1)), tuple(range(n, 2 * n))]
    return _mesh_object(coll, name, verts, faces, material)


def plane(coll, name, x0, x1, y0, y1, z, material, cuts=1):
    xs, ys = np.linspace(x0, x1, cuts + 1), np.linspace(y0, y1, cuts + 1)
    verts = [(x, y, z) for y in ys for x in xs]
    w = cuts + 1
    faces = [(j * w + i, j * w + i + 1, (j + 1) * w + i + 1, (j + 1) * w + i)
             for j in range(cuts) for i in range(cuts)]
    return _mesh_object(coll, name, verts, faces, material)


def build_street(scene):
    """Fill ``scene`` with a straight two-way street; return the LiDAR mount point
    (x, y, z) on the first pole."""
    asphalt = _material("Asphalt", (0.08, 0.08, 0.08), reflectivity=0.15)
    concrete = _material("Concrete", (0.5, 0.5, 0.48), reflectivity=0.45)
    facade = _material("Facade", (0.6, 0.55, 0.5))
    glass = _material("Glass", (0.8, 0.85, 0.9), roughness=0.02, metallic=1.0)
    paint = _material("CarPaint", (0.6, 0.05, 0.05), roughness=0.2)
    steel = _material("Steel", (0.55, 0.55, 0.55), roughness=0.3, metallic=1.0)

    road = _collection(scene, "Road")
    plane(road, "Road", -40, 40, -6, 6, 0.0, asphalt, cuts=8)
    walk = _collection(scene, "Sidewalk")
    box(walk, "Sidewalk North", (-40, 6, 0), (40, 9, 0.15), concrete)
    box(walk, "Sidewalk South", (-40, -9, 0), (40, -6, 0.15), concrete)
    build = _collection(scene, "Buildings")
    for i, (x0, x1, h) in enumerate([(-38, -22, 12), (-20, -4, 18), (-2, 14, 9), (16, 36, 15)]):
        box(build, f"Building N{i}", (x0, 10, 0), (x1, 20, h), glass if i == 2 else facade)
        box(build, f"Building S{i}", (x0 + 3, -20, 0), (x1 + 3, -10, h * 0.8), facade)
    poles = _collection(scene, "Poles")
    mounts = [(-12.0, 7.0), (12.0, -7.0)]
    for i, (x, y) in enumerate(mounts):
        cylinder(poles, f"Pole {i}", (x, y, 0.15), 0.12, 6.0, steel)
    cars = _collection(scene, "Vehicles")
    car = box(cars, "Car 0", (-2.25, -0.9, 0.3), (2.25, 0.9, 1.6), paint)
    car.location = (-20.0, -3.0, 0.0)
    car.keyframe_insert("location", frame=1)
    car.location = (20.0, -3.0, 0.0)
    car.keyframe_insert("location", frame=41)
    lob_coll = _collection(scene, "Regions")
    lob = plane(lob_coll, "InfraLOB", -15, 15, -9, 9, 0.0, asphalt)
    lob["rls_infralob"] = True
    lob.hide_render = True
    lob.display_type = "WIRE"
    scene.frame_start, scene.frame_end = 1, 41
    x, y = mounts[0]
    return (x, y - 0.3, 6.3)

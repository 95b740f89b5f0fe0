"""A small procedural street scene (the demo's), built with ``bpy.data`` only (no operators), so it
runs the same in the UI, ``blender -b`` and the ``bpy`` module.

Labels come from collection names (Road, Sidewalk, Buildings, Poles, Vehicles); the
region of interest is a flat rectangle marked ``rls_infralob``. The paper's three
placement scenes are in ``scenes/``.
"""

from .scenes.build import (
    box,
    collection as _collection,
    cylinder,
    plane,
    standard_materials,
)


def build_street(scene):
    """Fill ``scene`` with a straight two-way street; return the LiDAR mount point
    (x, y, z) on the first pole."""
    m = standard_materials()
    asphalt, concrete, facade = m["asphalt"], m["concrete"], m["facade"]
    glass, paint, steel = m["glass"], m["paint"], m["steel"]

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

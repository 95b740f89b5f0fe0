"""``intersection_sumo``: the four-way intersection (scene B, ``streets.py``) with its
traffic made by SUMO instead of by hand.

The static scene is scene B's (roads, sidewalks, buildings, poles and mounts, the
InfraLOB); its hand-made traffic is removed. A SUMO plain network with the same
geometry is written and netconverted: a signalised junction at the origin, four arms
of 60 m, each direction two 3.5 m lanes right of the road's middle line (|y| <= 7 along
x, |x| <= 7 along y, traffic keeping right as in scene B) and a 4 m sidewalk beyond
them, crossings at the junction. ``rls traffic generate``'s SUMO run over it
(``SEED``, ``RATE`` vehicles per hour, persons at a quarter of that, ``RUN_S`` seconds)
is imported over the scene's 60 frames from the start of its busiest stretch after a
``WARMUP_S`` warm-up (the most vehicle box centres in the InfraLOB, counted at SUMO's
steps): the signal's phases make some stretches much busier than others. Pedestrians
stand on the 0.15 m kerbs where the scene has them (SUMO's network is flat).
"""

import os
import shutil
import tempfile

import bpy
import numpy as np

from ...core.traffic.fcd import box_centre, load
from ...core.traffic.sumo_run import generate, netconvert_plain
from ..traffic import import_traffic
from . import streets

SEED = 33
RATE = 6000.0          # vehicles per hour over the four arms
WARMUP_S = 60.0        # no stretch starts before this (s)
RUN_S = 240.0
LOB_HALF = 12.0        # scene B's InfraLOB: x, y in [-12, 12]
ARM = 60.0
SPEED = 13.89          # 50 km/h


def network(out):
    r = streets.ROAD_HALF
    lanes, width = 2, r / 2
    nodes = [("C", 0.0, 0.0, "traffic_light"), ("E", ARM, 0.0, "dead_end"),
             ("W", -ARM, 0.0, "dead_end"), ("N", 0.0, ARM, "dead_end"),
             ("S", 0.0, -ARM, "dead_end")]
    edges = []
    for n in "EWNS":
        edges.append((f"C{n}", "C", n, lanes, width, streets.WALK, SPEED))
        edges.append((f"{n}C", n, "C", lanes, width, streets.WALK, SPEED))
    return netconvert_plain(nodes, edges, out)


def busiest(fcd, types, frames, fps):
    """The simulation time after ``WARMUP_S`` that starts the ``frames`` frames with the
    most vehicle box centres in the InfraLOB (counted at the FCD's steps, 1/fps apart)."""
    steps = int(round(fps * fcd.step))
    if steps != 1:
        raise ValueError("the FCD's step must be one frame")
    t0 = fcd.first
    counts = np.zeros(int(round((fcd.last - t0) * fps)) + 1)
    for tr in fcd.tracks.values():
        vt = types[tr.type]
        if vt.label != "vehicle":
            continue
        cx, cy, _ = box_centre(tr.x, tr.y, tr.angle, vt.length)
        inside = (np.abs(cx) <= LOB_HALF) & (np.abs(cy) <= LOB_HALF)
        np.add.at(counts, np.round((tr.times[inside] - t0) * fps).astype(int), 1)
    window = np.convolve(counts, np.ones(frames), mode="valid")   # window starting at i
    first = int(np.ceil((WARMUP_S - t0) * fps))
    return t0 + (first + int(np.argmax(window[first:]))) / fps


def _remove_hand_traffic():
    for name in ("Vehicles", "Pedestrians", "Cyclists"):
        coll = bpy.data.collections.get(name)
        if coll is None:
            continue
        for obj in list(coll.objects):
            mesh, ad = obj.data, obj.animation_data
            action = ad.action if ad is not None else None
            bpy.data.objects.remove(obj)
            if mesh is not None and mesh.users == 0:
                bpy.data.meshes.remove(mesh)
            if action is not None and action.users == 0:
                bpy.data.actions.remove(action)


def build_intersection_sumo(scene):
    info = streets.build_intersection(scene)
    _remove_hand_traffic()
    colls = {c.name: c for c in bpy.data.collections}
    kerb = streets._surface(colls)
    tmp = tempfile.mkdtemp(prefix="rls-scene-sumo-")
    try:
        net = network(os.path.join(tmp, "intersection.net.xml"))
        fcd_path = os.path.join(tmp, "intersection.xml")
        fps = scene.render.fps / scene.render.fps_base
        n = scene.frame_end - scene.frame_start + 1
        generate(net, fcd_path, duration=RUN_S, rate=RATE, seed=SEED, step=1.0 / fps)
        fcd, types = load(fcd_path)
        begin = busiest(fcd, types, n, fps)
        end = begin + (n - 1) / fps
        got = import_traffic(scene, fcd, types, begin=begin, end=end, ground=kerb)
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
    objs = bpy.data.collections[got["collection"]].objects
    by = {lab: sorted(o.name for o in objs if o["rls_label"] == lab)
          for lab in ("vehicle", "pedestrian", "cyclist")}
    info.update(vehicles=by["vehicle"], parked=[], pedestrians=by["pedestrian"],
                cyclists=by["cyclist"], traffic=sorted(o.name for o in objs),
                sumo={"seed": SEED, "rate_veh_h": RATE, "begin_s": begin,
                      "objects": got["objects"], "object_frames": got["object_frames"]})
    return info

"""The three scenes of the paper's placement experiments (Cai et al., Fig. "placements"):

A ``t_junction``   a T-junction: an east-west main road, a side road to the north
B ``intersection`` a four-way intersection of two 14 m roads
C ``four_lane``    a straight two-way four-lane road

Each has labelled road and sidewalk surfaces, buildings (one with a glass facade),
traffic-light and street-light poles marked as LiDAR mounts, an InfraLOB over the
junction area, and traffic through it over frames 1-60 at 10 frames per second (one
frame per 10 Hz sweep, as LiDAR datasets are recorded):

* the first cars, kept as they were ('Car west', 'Car east', ...: other tests, the
  demo and the docs refer to them): 17 m/s (24 m/s on the four-lane road), two pairs
  of them meeting (see tests/blender/test_scene_traffic.py);
* vehicles in both directions on every lane, straight and turning (``traffic.py``:
  their boxes head along their paths through the turns), at 5-15 m/s, a few parked
  ones (cars, vans, a truck) in collection ``Vehicles``; pedestrians (``Pedestrians``)
  on the sidewalks and across a road, cyclists (``Cyclists``) on the sidewalks.

No two bodies overlap (but for the first cars' meetings), vehicles stay on the road,
and each InfraLOB holds at least 200 vehicle-frames (a vehicle whose box centre is in
the region at a frame), as the tests check. Roads are 14 m wide (four 3.5 m lanes),
sidewalks 4 m wide and 0.15 m high. Every builder fills an empty scene and returns a
dict with the region and mount names and the traffic's.
"""

import numpy as np

from .build import box, car, collection, infralob, material, mount_pole, plane, standard_materials
from .traffic import Route, mover, parked

ROAD_HALF = 7.0
WALK = 4.0
CURB = 0.15
TRAFFIC_LIGHT_H = 6.0
STREET_LIGHT_H = 8.0
FRAMES = (1, 60)
FPS = 10
# lane centres: 1.75 m (inner) and 5.25 m (outer) either side of a road's middle line;
# traffic keeps right (westbound on +y of a road along x, northbound on +x of one along y)
INNER, OUTER = 1.75, 5.25
SIZES = {"Car": (4.5, 1.8, 1.5), "Van": (5.2, 2.0, 2.2), "Truck": (9.0, 2.5, 3.2),
         "Pedestrian": (0.6, 0.6, 1.75), "Cyclist": (1.8, 0.6, 1.7)}


def _base(scene):
    mats = standard_materials()
    colls = {name: collection(scene, name) for name in
             ("Road", "Sidewalk", "Buildings", "Traffic Lights", "Poles", "Vehicles",
              "Pedestrians", "Cyclists")}
    scene.frame_start, scene.frame_end = FRAMES
    scene.render.fps, scene.render.fps_base = FPS, 1.0
    scene.frame_set(FRAMES[0])
    return mats, colls


def _walk(colls, mats, name, x0, x1, y0, y1):
    box(colls["Sidewalk"], name, (x0, y0, 0.0), (x1, y1, CURB), mats["concrete"])


def _building(colls, mats, name, x0, x1, y0, y1, h, glass=False):
    box(colls["Buildings"], name, (x0, y0, 0.0), (x1, y1, h), mats["glass" if glass else "facade"])


def _surface(colls):
    """Height of the ground under (N, 2) xy points: the kerb on the sidewalks (the boxes
    in collection Sidewalk), 0 elsewhere."""
    rects = []
    for o in colls["Sidewalk"].objects:
        co = np.array([v.co[:] for v in o.data.vertices])
        rects.append((co[:, 0].min(), co[:, 0].max(), co[:, 1].min(), co[:, 1].max()))
    rects = np.array(rects)

    def z(xy):
        x, y = xy[:, 0, None], xy[:, 1, None]
        on = (x >= rects[:, 0]) & (x <= rects[:, 1]) & (y >= rects[:, 2]) & (y <= rects[:, 3])
        return np.where(on.any(axis=1), CURB, 0.0)
    return z


def _traffic(scene, colls, routes, movers, still):
    """The traffic beside the legacy cars. ``movers``: (name, route key, s0), the kind
    (Car, Van, Truck, Pedestrian, Cyclist) the name's first word, ``s0`` the metres
    along the route at the first frame; ``still``: (name, x, y, heading degrees) of
    parked vehicles."""
    mats = {"Vehicles": standard_materials()["paint"],
            "Pedestrians": material("Pedestrian", (0.2, 0.25, 0.45)),
            "Cyclists": material("Cyclist", (0.1, 0.45, 0.2))}
    coll = {"Car": "Vehicles", "Van": "Vehicles", "Truck": "Vehicles",
            "Pedestrian": "Pedestrians", "Cyclist": "Cyclists"}
    for name, key, s0 in movers:
        kind = name.split()[0]
        clearance = 0.3 if coll[kind] == "Vehicles" else 0.0
        mover(scene, colls[coll[kind]], name, SIZES[kind], mats[coll[kind]], routes[key], s0,
              clearance=clearance)
    for name, x, y, heading in still:
        kind = name.split()[0]
        parked(colls["Vehicles"], name, SIZES[kind], mats["Vehicles"], x, y, heading)


def _result(lob, colls):
    mounts = sorted(o.name for c in ("Traffic Lights", "Poles") for o in colls[c].objects
                    if o.get("rls_mount"))
    names = {c: sorted(o.name for o in colls[c].objects)
             for c in ("Vehicles", "Pedestrians", "Cyclists")}
    parked_ = sorted(o.name for o in colls["Vehicles"].objects if o.animation_data is None)
    return {"infralob": lob.name, "mounts": mounts,
            "vehicles": names["Vehicles"], "parked": parked_,
            "pedestrians": names["Pedestrians"], "cyclists": names["Cyclists"],
            "traffic": sorted(n for v in names.values() for n in v)}


def _t_junction_routes(colls):
    """Routes through the T-junction (main road along x, side road north) at 8-9 m/s:
    straight along the main road, a right turn into the side road (radius 5 m, 5.5
    m/s) and a left one (radius 7 m, 6.5 m/s); paths on the sidewalks and across the
    side road."""
    z = _surface(colls)
    end, i, o = 55.0, INNER, OUTER
    return {
        "westbound inner": Route(end, i, 180).straight(2 * end, 8),
        "westbound outer": Route(end, o, 180).straight(2 * end, 9),
        "eastbound inner": Route(-end, -i, 0).straight(2 * end, 9),
        "eastbound outer": Route(-end, -o, 0).straight(2 * end, 9),
        "west to north": Route(end, o, 180).straight(end - i - 5, 9).turn(5, -90, 5.5)
                                           .straight(end - o - 5, 9),
        "east to north": Route(-end, -i, 0).straight(end - o, 9).turn(7, 90, 6.5)
                                           .straight(end - o, 9),
        "sidewalk S east": Route(-20, -9.9, 0, z).straight(40, 1.4),
        "sidewalk S west": Route(20, -10.5, 180, z).straight(40, 1.3),
        "sidewalk NW": Route(-22, 9.3, 0, z).straight(12.2, 1.4).turn(0.5, 90, 1.4)
                                            .straight(30, 1.4),
        "crossing side road": Route(-16, 9.6, 0, z).straight(20, 1.4),
        "cycle track S east": Route(-45, -7.8, 0, z).straight(90, 5.0),
        "cycle track S west": Route(45, -8.8, 180, z).straight(90, 4.5),
        "cycle track NW": Route(-45, 8.0, 0, z).straight(35, 5.0).turn(2.0, 90, 4.0)
                                               .straight(50, 5.0),
    }


# (name, route, metres along it at frame 1); the kind is the name's first word. The
# starts are chosen so that no two bodies meet (the lanes' turns and crossings are
# timed around each other and around the first cars).
T_JUNCTION_MOVERS = [
    ("Pedestrian 1", "sidewalk S east", 8.0),
    ("Pedestrian 2", "sidewalk S west", 12.0),
    ("Pedestrian 3", "sidewalk NW", 2.0),
    ("Pedestrian 4", "crossing side road", 4.0),
    ("Cyclist 1", "cycle track S east", 30.0),
    ("Cyclist 2", "cycle track S west", 38.0),
    ("Cyclist 3", "cycle track NW", 10.5),
    ("Car eastbound inner 1", "eastbound inner", 51.9),
    ("Car eastbound inner 2", "eastbound inner", 40.2),
    ("Van eastbound inner 3", "eastbound inner", 28.5),
    ("Car eastbound inner 4", "eastbound inner", 16.8),
    ("Car east to north 1", "east to north", 5.1),
    ("Car west to north 1", "west to north", 20.0),
    ("Car west to north 2", "west to north", 34.5),
    ("Car westbound outer 1", "westbound outer", 43.0),
    ("Car westbound outer 2", "westbound outer", 51.5),
    ("Car westbound outer 3", "westbound outer", 4.0),
    ("Car westbound inner 1", "westbound inner", 0.0),   # behind 'Car west'
    ("Car eastbound outer 1", "eastbound outer", 0.0),   # behind 'Car east'
]
# (name, x, y, heading degrees): at the kerb of the side road, out of the turns' way
T_JUNCTION_PARKED = [
    ("Car parked 1", 5.75, 16.0, 90),
    ("Van parked 2", 5.75, 22.5, 90),
    ("Truck parked 3", 5.75, 33.0, 90),
]


def build_t_junction(scene):
    """Scene A. Main road along x (|y| <= 7), side road north (|x| <= 7),
    InfraLOB x in [-15, 15], y in [-11, 11] (660 m^2)."""
    mats, colls = _base(scene)
    r, e = ROAD_HALF, ROAD_HALF + WALK
    plane(colls["Road"], "Main road", -60, 60, -r, r, 0.0, mats["asphalt"], cuts=12)
    plane(colls["Road"], "Side road", -r, r, r, 60, 0.0, mats["asphalt"], cuts=6)
    _walk(colls, mats, "Sidewalk S", -60, 60, -e, -r)
    _walk(colls, mats, "Sidewalk NW", -60, -r, r, e)
    _walk(colls, mats, "Sidewalk NE", r, 60, r, e)
    _walk(colls, mats, "Sidewalk side W", -e, -r, e, 60)
    _walk(colls, mats, "Sidewalk side E", r, e, e, 60)
    for i, (x0, x1, h) in enumerate([(-55, -35, 14), (-32, -8, 20), (-5, 12, 10), (15, 40, 16)]):
        _building(colls, mats, f"Building S{i}", x0, x1, -30, -e - 1, h)
    _building(colls, mats, "Building NW", -45, -e - 1, e + 1, 40, 18)
    _building(colls, mats, "Building NE", e + 1, 45, e + 1, 40, 24, glass=True)
    tl, sl = colls["Traffic Lights"], colls["Poles"]
    m = r + 2.0
    mount_pole(tl, "TL NW", -m, m, TRAFFIC_LIGHT_H, mats["steel"], "traffic_light", (-m, 0))
    mount_pole(tl, "TL NE", m, m, TRAFFIC_LIGHT_H, mats["steel"], "traffic_light", (m, 0))
    mount_pole(tl, "TL SW", -m, -m, TRAFFIC_LIGHT_H, mats["steel"], "traffic_light", (-m, 0))
    mount_pole(tl, "TL SE", m, -m, TRAFFIC_LIGHT_H, mats["steel"], "traffic_light", (m, 0))
    mount_pole(sl, "SL S", 0.0, -m, STREET_LIGHT_H, mats["steel"], "street_light")
    for x in (-25.0, 25.0):
        mount_pole(sl, f"SL N {x:+.0f}", x, m, STREET_LIGHT_H, mats["steel"], "street_light")
    v = colls["Vehicles"]
    car(v, "Car west", mats["paint"], [(50, 1.75), (-50, 1.75)], [1, 60])
    car(v, "Car east", mats["paint"], [(-50, -5.25), (50, -5.25)], [1, 60])
    car(v, "Car turning", mats["paint"], [(-3.5, 50), (-3.5, 5), (-8, 1.75), (-50, 1.75)],
        [1, 30, 36, 60])
    _traffic(scene, colls, _t_junction_routes(colls), T_JUNCTION_MOVERS, T_JUNCTION_PARKED)
    lob = infralob(scene, "InfraLOB", -15, 15, -e, e)
    return _result(lob, colls)


def _intersection_routes(colls):
    """Routes through the four-way intersection at 8-9 m/s: right turns from each outer
    lane into the next outer lane (radius 3.5 m, 5 m/s, around the square kerb
    corners), straight on the inner lanes, a left turn (radius 7 m, 6.5 m/s); paths on
    the sidewalks and across the south road."""
    z = _surface(colls)
    end, i, o = 55.0, INNER, OUTER
    arm = end - o - 3.5  # straight before and after a right turn

    def right(x, y, heading):
        return Route(x, y, heading).straight(arm, 9).turn(3.5, -90, 5).straight(arm, 9)
    return {
        "west to north": right(end, o, 180),
        "north to east": right(o, -end, 90),
        "east to south": right(-end, -o, 0),
        "south to west": right(-o, end, 270),
        "eastbound inner": Route(-end, -i, 0).straight(2 * end, 9),
        "westbound inner": Route(end, i, 180).straight(2 * end, 8),
        "northbound inner": Route(i, -end, 90).straight(2 * end, 8),
        "south to east": Route(-i, end, 270).straight(end - o, 9).turn(7, 90, 6.5)
                                            .straight(end - o, 9),
        "sidewalk NE": Route(30, 9.5, 180, z).straight(20.5, 1.4).turn(0.5, -90, 1.4)
                                             .straight(40, 1.4),
        "sidewalk SW": Route(-30, -9.5, 0, z).straight(20.5, 1.3).turn(0.5, -90, 1.3)
                                             .straight(40, 1.3),
        "sidewalk SE": Route(9.6, -40, 90, z).straight(31, 1.5),
        "crossing south road": Route(-20, -9.2, 0, z).straight(40, 1.4),
        "cycle track NW": Route(-45, 8.0, 0, z).straight(35, 5.0).turn(2.0, 90, 4.0)
                                               .straight(50, 5.0),
        "cycle track SE": Route(8.0, -45, 90, z).straight(35, 5.0).turn(2.0, -90, 4.0)
                                               .straight(50, 5.0),
        "cycle track SW": Route(-8.0, -45, 90, z).straight(35, 4.5).turn(2.0, 90, 4.0)
                                                .straight(50, 4.5),
    }


INTERSECTION_MOVERS = [
    ("Pedestrian 1", "sidewalk NE", 12.0),
    ("Pedestrian 2", "sidewalk SW", 14.0),
    ("Pedestrian 3", "sidewalk SE", 21.0),
    ("Pedestrian 4", "crossing south road", 23.0),
    ("Cyclist 1", "cycle track NW", 33.0),
    ("Cyclist 2", "cycle track SE", 33.0),
    ("Cyclist 3", "cycle track SW", 15.0),
    ("Car westbound inner 1", "westbound inner", 0.0),    # behind 'Car west'
    ("Car northbound inner 1", "northbound inner", 0.0),  # behind 'Car north'
    ("Car east to south 1", "east to south", 0.0),        # behind 'Car east'
    ("Car south to west 1", "south to west", 0.0),        # behind 'Car south'
    ("Car west to north 1", "west to north", 40.5),
    ("Car west to north 2", "west to north", 28.0),
    ("Car west to north 3", "west to north", 14.5),
    ("Car north to east 1", "north to east", 15.4),
    ("Car north to east 2", "north to east", 1.9),
    ("Car south to west 2", "south to west", 44.0),
    ("Car eastbound inner 1", "eastbound inner", 38.0),
    ("Van eastbound inner 2", "eastbound inner", 47.0),
    ("Car eastbound inner 3", "eastbound inner", 4.5),
    ("Car south to east 1", "south to east", 0.0),
    ("Car south to east 2", "south to east", 59.0),
]
# at the kerb beyond where the moving traffic gets to by frame 60
INTERSECTION_PARKED = [
    ("Truck parked 1", 5.75, 50.0, 90),
    ("Van parked 2", 56.0, -5.75, 0),
]


def build_intersection(scene):
    """Scene B. Roads along x and y (|y| <= 7, |x| <= 7), corner traffic lights at
    (+-9, +-9), InfraLOB x, y in [-12, 12] (576 m^2)."""
    mats, colls = _base(scene)
    r, e = ROAD_HALF, ROAD_HALF + WALK
    plane(colls["Road"], "Road EW", -60, 60, -r, r, 0.0, mats["asphalt"], cuts=12)
    plane(colls["Road"], "Road N", -r, r, r, 60, 0.0, mats["asphalt"], cuts=6)
    plane(colls["Road"], "Road S", -r, r, -60, -r, 0.0, mats["asphalt"], cuts=6)
    for sx, ew in ((1, "E"), (-1, "W")):
        for sy, ns in ((1, "N"), (-1, "S")):
            xs = sorted((sx * r, sx * 60))
            ys = sorted((sy * r, sy * e))
            _walk(colls, mats, f"Sidewalk {ns}{ew} along x", xs[0], xs[1], ys[0], ys[1])
            xs2 = sorted((sx * r, sx * e))
            ys2 = sorted((sy * e, sy * 60))
            _walk(colls, mats, f"Sidewalk {ns}{ew} along y", xs2[0], xs2[1], ys2[0], ys2[1])
            bx = sorted((sx * (e + 1), sx * 40))
            by = sorted((sy * (e + 1), sy * 40))
            glass = (ns, ew) == ("N", "E")
            _building(colls, mats, f"Building {ns}{ew}", bx[0], bx[1], by[0], by[1],
                      {"NE": 22, "NW": 15, "SE": 12, "SW": 18}[ns + ew], glass=glass)
    tl, sl = colls["Traffic Lights"], colls["Poles"]
    m = r + 2.0
    for sx, ew in ((1, "E"), (-1, "W")):
        for sy, ns in ((1, "N"), (-1, "S")):
            mount_pole(tl, f"TL {ns}{ew}", sx * m, sy * m, TRAFFIC_LIGHT_H, mats["steel"],
                       "traffic_light", (sx * m, 0.0))
    for x in (-25.0, 25.0):
        mount_pole(sl, f"SL {x:+.0f} N", x, m, STREET_LIGHT_H, mats["steel"], "street_light")
        mount_pole(sl, f"SL {x:+.0f} S", x, -m, STREET_LIGHT_H, mats["steel"], "street_light")
    v = colls["Vehicles"]
    car(v, "Car west", mats["paint"], [(50, 1.75), (-50, 1.75)], [1, 60])
    car(v, "Car east", mats["paint"], [(-50, -5.25), (50, -5.25)], [1, 60])
    car(v, "Car north", mats["paint"], [(1.75, -50), (1.75, 50)], [1, 60])
    car(v, "Car south", mats["paint"], [(-5.25, 50), (-5.25, -50)], [1, 60])
    _traffic(scene, colls, _intersection_routes(colls), INTERSECTION_MOVERS,
             INTERSECTION_PARKED)
    lob = infralob(scene, "InfraLOB", -12, 12, -12, 12)
    return _result(lob, colls)


def _four_lane_routes(colls):
    """Routes along the four-lane road (each lane from one end to the other, 15 m/s:
    behind the legacy cars, which drive faster) and on its sidewalks."""
    z = _surface(colls)
    end, i, o = 75.0, INNER, OUTER
    return {
        "westbound inner": Route(end, i, 180).straight(2 * end, 15),
        "westbound outer": Route(end, o, 180).straight(2 * end, 15),
        "eastbound inner": Route(-end, -i, 0).straight(2 * end, 15),
        "eastbound outer": Route(-end, -o, 0).straight(2 * end, 15),
        "sidewalk N west": Route(20, 9.5, 180, z).straight(50, 1.4),
        "sidewalk N east": Route(-20, 10.4, 0, z).straight(50, 1.3),
        "sidewalk S east": Route(-15, -9.5, 0, z).straight(50, 1.5),
        "sidewalk S west": Route(15, -10.4, 180, z).straight(50, 1.2),
        "cycle track N west": Route(50, 8.0, 180, z).straight(100, 5.0),
        "cycle track N east": Route(-50, 8.8, 0, z).straight(100, 4.5),
        "cycle track S east": Route(-50, -8.0, 0, z).straight(100, 5.5),
    }


# Every lane has one of the first cars sweeping it from end to end at 24 m/s, so the new
# vehicles follow them in from the road's ends (and C has the fewest vehicle-frames).
FOUR_LANE_MOVERS = [
    ("Pedestrian 1", "sidewalk N west", 10.0),
    ("Pedestrian 2", "sidewalk N east", 12.0),
    ("Pedestrian 3", "sidewalk S east", 6.0),
    ("Pedestrian 4", "sidewalk S west", 8.0),
    ("Cyclist 1", "cycle track N west", 40.0),
    ("Cyclist 2", "cycle track N east", 30.0),
    ("Cyclist 3", "cycle track S east", 28.0),
    ("Car westbound inner 1", "westbound inner", 0.0),    # behind 'Car west 0'
    ("Car westbound outer 1", "westbound outer", 19.0),   # behind 'Car west 1'
    ("Car eastbound inner 1", "eastbound inner", 0.0),    # behind 'Car east 0'
    ("Car eastbound outer 1", "eastbound outer", 19.0),   # behind 'Car east 1'
    ("Van eastbound outer 2", "eastbound outer", 1.0),
]
# at the westbound kerb, behind where 'Car west 1' starts
FOUR_LANE_PARKED = [
    ("Truck parked 1", 66.0, OUTER + 0.4, 180),
    ("Van parked 2", 75.0, OUTER + 0.4, 180),
]


def build_four_lane(scene):
    """Scene C. A straight road along x (|y| <= 7, four 3.5 m lanes), sidewalks to
    |y| = 11, street lights every 20 m on both sides, InfraLOB x in [-25, 25],
    y in [-11, 11] (1100 m^2). The mounts facing each other at x = 0 are 'SL N +0'
    and 'SL S +0'."""
    mats, colls = _base(scene)
    r, e = ROAD_HALF, ROAD_HALF + WALK
    plane(colls["Road"], "Road", -80, 80, -r, r, 0.0, mats["asphalt"], cuts=16)
    _walk(colls, mats, "Sidewalk N", -80, 80, r, e)
    _walk(colls, mats, "Sidewalk S", -80, 80, -e, -r)
    for i, (x0, x1, h) in enumerate([(-70, -42, 15), (-40, -12, 24), (-10, 10, 12),
                                     (12, 38, 18), (40, 70, 10)]):
        _building(colls, mats, f"Building N{i}", x0, x1, e + 1, 32, h, glass=(i == 2))
        _building(colls, mats, f"Building S{i}", x0 + 4, x1 + 4, -32, -e - 1, h * 0.8)
    sl = colls["Poles"]
    m = r + 2.0
    for x in (-40.0, -20.0, 0.0, 20.0, 40.0):
        mount_pole(sl, f"SL N {x:+.0f}", x, m, STREET_LIGHT_H, mats["steel"], "street_light")
        mount_pole(sl, f"SL S {x:+.0f}", x, -m, STREET_LIGHT_H, mats["steel"], "street_light")
    v = colls["Vehicles"]
    for i, y in enumerate((1.75, 5.25)):
        car(v, f"Car west {i}", mats["paint"], [(70 - 20 * i, y), (-70 - 20 * i, y)], [1, 60])
        car(v, f"Car east {i}", mats["paint"], [(-70 + 20 * i, -y), (70 + 20 * i, -y)], [1, 60])
    _traffic(scene, colls, _four_lane_routes(colls), FOUR_LANE_MOVERS, FOUR_LANE_PARKED)
    lob = infralob(scene, "InfraLOB", -25, 25, -e, e)
    return _result(lob, colls)

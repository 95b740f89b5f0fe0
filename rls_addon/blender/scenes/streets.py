"""The three scenes of the paper's placement experiments (Cai et al., Fig. "placements"):

A ``t_junction``   a T-junction: an east-west main road, a side road to the north
B ``intersection`` a four-way intersection of two 14 m roads
C ``four_lane``    a straight two-way four-lane road

Each has labelled road and sidewalk surfaces, buildings (one with a glass facade),
traffic-light and street-light poles marked as LiDAR mounts, an InfraLOB over the
junction area, and cars driving through it (collection ``Vehicles``, frames 1-60 at
10 frames per second, one frame per 10 Hz sweep as LiDAR datasets are recorded: the
cars drive at 15-18 m/s, 9 m/s through the turn).
Roads are 14 m wide (four 3.5 m lanes), sidewalks 4 m wide and 0.15 m high.
Every builder fills an empty scene and returns a dict with the region and mount names.
"""

from .build import box, car, collection, infralob, mount_pole, plane, standard_materials

ROAD_HALF = 7.0
WALK = 4.0
CURB = 0.15
TRAFFIC_LIGHT_H = 6.0
STREET_LIGHT_H = 8.0
FRAMES = (1, 60)
FPS = 10


def _base(scene):
    mats = standard_materials()
    colls = {name: collection(scene, name) for name in
             ("Road", "Sidewalk", "Buildings", "Traffic Lights", "Poles", "Vehicles")}
    scene.frame_start, scene.frame_end = FRAMES
    scene.render.fps, scene.render.fps_base = FPS, 1.0
    scene.frame_set(FRAMES[0])
    return mats, colls


def _walk(colls, mats, name, x0, x1, y0, y1):
    box(colls["Sidewalk"], name, (x0, y0, 0.0), (x1, y1, CURB), mats["concrete"])


def _building(colls, mats, name, x0, x1, y0, y1, h, glass=False):
    box(colls["Buildings"], name, (x0, y0, 0.0), (x1, y1, h), mats["glass" if glass else "facade"])


def _result(lob, colls):
    mounts = sorted(o.name for c in ("Traffic Lights", "Poles") for o in colls[c].objects
                    if o.get("rls_mount"))
    return {"infralob": lob.name, "mounts": mounts,
            "vehicles": sorted(o.name for o in colls["Vehicles"].objects)}


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
    lob = infralob(scene, "InfraLOB", -15, 15, -e, e)
    return _result(lob, colls)


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
    lob = infralob(scene, "InfraLOB", -12, 12, -12, 12)
    return _result(lob, colls)


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
    lob = infralob(scene, "InfraLOB", -25, 25, -e, e)
    return _result(lob, colls)

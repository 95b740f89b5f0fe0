"""The static scene's watertight re-check in an instanced cast (moving objects as
Embree instances, ``core/world/instancing.py``): done in the compiled loop's threads
after refinement, it wins back the same rays with the same bits as the numpy
reference (``InstancedWorld._finish``)."""

import numpy as np
import pytest

from rls_addon.core.scene.geometry import ObjectInfo, SceneGeometry
from rls_addon.core.scene.motion import Track
from rls_addon.core.world.bodies import PreparedScene, RigidBodies
from rls_addon.core.world.world import World

from .test_instancing import T, Embree, car, pose, realistic_turn


def cracked_street():
    """A ground and a wall each cut into a fine grid of triangles (rays aimed at their
    shared edges and vertices slip through float32 traversals: what the watertight
    re-check wins back), one table for every body."""
    from rls_addon.core.scene.geometry import MaterialInfo

    def grid(p0, u, v, n):
        s = np.linspace(0.0, 1.0, n + 1)
        ss, tt = np.meshgrid(s, s, indexing="ij")
        verts = np.asarray(p0) + ss.reshape(-1, 1) * np.asarray(u) + tt.reshape(-1, 1) * np.asarray(v)
        i, j = np.meshgrid(np.arange(n), np.arange(n), indexing="ij")
        a = (i * (n + 1) + j).ravel()
        tris = np.concatenate([np.stack([a, a + n + 1, a + n + 2], 1),
                               np.stack([a, a + n + 2, a + 1], 1)])
        return verts, tris

    gv, gt = grid((-40, -40, -1.5), (80, 0, 0), (0, 80, 0), 60)
    wv, wt = grid((30, -40, -1.5), (0, 80, 0), (0, 0, 9.5), 40)
    v = np.concatenate([gv, wv])
    t = np.concatenate([gt, wt + len(gv)])
    obj = np.r_[np.zeros(len(gt), np.int64), np.ones(len(wt), np.int64)]
    return SceneGeometry(v, t, obj, np.zeros(len(t), np.int64),
                         [ObjectInfo("ground", 1, 1), ObjectInfo("wall", 2, 2)],
                         [MaterialInfo("default")]), v


def street_cars_and_rays(moving_sensor):
    """(static scene, the cars' RigidBodies, origins, directions, times): rays aimed at
    the cracked street's vertices and edge midpoints, with cars in front of some of
    them, from one origin or from an origin per ray (a driving sensor, outside every
    hull box)."""
    fast = Embree.configured(robust=False)
    g, verts = cracked_street()
    base = len(g.objects)
    objects = g.objects + [ObjectInfo(f"car {k}", 11, 10 + k) for k in range(3)]
    g = SceneGeometry(g.vertices, g.triangles, g.tri_object, g.tri_material, objects,
                      g.materials)
    parts = [(car(base, objects), Track([0.0, T], [pose(10, -6, -0.8), pose(10, -4, -0.8)])),
             (car(base + 1, objects), realistic_turn()),
             (car(base + 2, objects), Track.fixed(pose(0, 9, -0.8, 30)))]
    rb = RigidBodies(parts, fast)
    static = PreparedScene(g, np.zeros(3), 100.0, fast)
    rng = np.random.default_rng(4)
    targets = np.concatenate([verts, (verts[g.triangles[:, 0]] + verts[g.triangles[:, 1]]) / 2])
    targets = targets[rng.permutation(len(targets))[:60000]]
    if moving_sensor:
        times = np.sort(rng.uniform(0.0, T, len(targets)))
        origins = np.c_[-3 + 15 * times, 0.5 + 0 * times, 1.0 + 0 * times]
    else:
        times = rng.uniform(0.0, T, len(targets))
        origins = np.array([[0.2, 0.5, 1.0]])
    d = targets - origins
    d /= np.linalg.norm(d, axis=1)[:, None]
    return static, rb, origins, d, times


@pytest.mark.parametrize("moving_sensor", [False, True])
def test_the_instanced_recheck_in_the_loop_equals_numpys(moving_sensor):
    """The static scene's re-check of the rays that miss it in an instanced cast, done
    in the loop's threads after refinement, wins back the same rays with the same bits
    as the numpy reference (InstancedWorld._finish), from one origin (a crack counts
    only before the ray's moving hit) and from an origin per ray (a driving sensor),
    with cars in front of some of the cracks."""
    static, rb, origins, d, times = street_cars_and_rays(moving_sensor)
    got = []
    for compiled in (True, False):
        static.caster.compiled, static.caster.retried = compiled, 0
        static.instanced_cache.clear()
        world = World(static, [rb])
        assert world.instanced is not None and world.instanced.first == 1
        got.append((world.cast(origins, d, times, 100.0), static.caster.retried))
    static.caster.compiled = True
    (a, ra), (b, rb_) = got
    assert ra == rb_ > 100  # many rays aimed at the cracks were re-cast
    for x, y in zip(a, b):
        assert x.tobytes() == y.tobytes()
    body = a[1]
    assert np.count_nonzero(body >= 1) > 100 and np.count_nonzero(body == 0) > 10000
    static.instanced_cache.clear()
    unchecked = World(static, [rb]).cast(origins, d, times, 100.0, watertight=False)[1]
    assert np.count_nonzero((unchecked < 0) & (body == 0)) > 500  # cracks won back


@pytest.mark.parametrize("compiled", [True, False], ids=["compiled", "numpy"])
def test_a_driving_sensor_outside_the_hull_rechecks_only_up_to_its_moving_hits(
        compiled, monkeypatch):
    """Origins per ray (a driving sensor) that all lie outside every hull box re-check a
    ray that hit a car only where a hull box comes before the car, as one origin does:
    the same bits as re-checking every such ray (what a driving sensor did before,
    re-casting each ray that hit a car), with far fewer rays re-cast."""
    static, rb, origins, d, times = street_cars_and_rays(moving_sensor=True)
    caster = static.caster
    assert not caster._starts_inside(origins)
    got = []
    for limited in (True, False):
        if not limited:  # every origin taken as inside a box: every such ray re-cast
            monkeypatch.setattr(type(caster), "_starts_inside", lambda self, o: True)
        caster.compiled, caster.retried = compiled, 0
        static.instanced_cache.clear()
        got.append((World(static, [rb]).cast(origins, d, times, 100.0), caster.retried))
    caster.compiled = True
    (a, limited), (b, every) = got
    for x, y in zip(a, b):
        assert x.tobytes() == y.tobytes()
    assert np.count_nonzero(a[1] >= 1) > 400  # rays that hit a car (541)
    assert every - limited > 400  # most of them were re-cast before (1,872 against 1,331)


def test_origins_whose_bounds_meet_a_hull_box_count_as_inside():
    """Per-ray origins are judged by the box around them: outside every hull box only
    when that box meets none (one origin inside a box among many outside makes it
    inside)."""
    static, _, origins, _, _ = street_cars_and_rays(moving_sensor=True)
    caster = static.caster
    assert not caster._starts_inside(origins)
    inside = origins.copy()
    inside[-1] = (caster.box_lo[0] + caster.box_hi[0]) / 2
    assert caster._starts_inside(inside)
    assert caster._starts_inside(inside[-1:]) and not caster._starts_inside(origins[:1])


def test_instances_attached_in_c_cast_as_those_attached_call_by_call(monkeypatch):
    """The instances of a sweep's moving objects attached to the top-level Embree scene
    in C (native/c/instances.c) and one ctypes call at a time (``_attach_each``, the
    reference) give the same casts to the bit: a car crossing the rays at 120 m/s (two
    steps), one turning at 40 degrees a second (65 steps) and a parked one, in front
    of a street;
    rays spread over the sweep, so which of them meet a car depends on every step."""
    from rls_addon.core.casting import embree_api

    from .test_instancing import bodies, street

    assert embree_api.ATTACH_INSTANCES.get() is not None  # the library is built here
    fast = Embree.configured(robust=False)
    g, rb = bodies(street(), fast)
    rb.tracks = [Track([0.0, T], [pose(10, -6, -0.8), pose(10, 6, -0.8)]), realistic_turn(),
                 rb.tracks[2]]
    static = PreparedScene(g, np.zeros(3), 100.0, fast)
    rng = np.random.default_rng(8)
    n = 40000
    az, el = rng.uniform(-np.pi, np.pi, n), rng.uniform(-0.3, 0.1, n)
    d = np.c_[np.cos(el) * np.cos(az), np.cos(el) * np.sin(az), np.sin(el)]
    times = np.sort(rng.uniform(0.0, T, n))
    origins = np.array([[0.0, 0.0, 0.5]])
    got = []
    for compiled in (True, False):
        monkeypatch.setattr(embree_api, "compiled", compiled)
        static.instanced_cache.clear()
        world = World(static, [rb])
        # traced as instances (a library whose instances do not move as their steps
        # say fails the process's instancing probe: every body is cast the portable way)
        assert world.instanced is not None and not world.instanced.portable
        got.append(world.cast(origins, d, times, 100.0))
    for x, y in zip(*got):
        assert x.tobytes() == y.tobytes()
    body, tri = got[0][1], got[0][2]
    car_of = np.searchsorted(rb.tri_start, np.maximum(tri, 0), side="right") - 1
    for k in range(3):  # every car is hit
        assert np.count_nonzero((body == 1) & (car_of == k)) > 20

"""Everything a sweep can hit, cast as one: the static scene and the moving bodies."""

from dataclasses import dataclass, field

import numpy as np

from .bodies import PreparedScene
from ..scene.geometry import ObjectInfo, SceneGeometry, hit_body, pair_rows
from .instancing import InstancedWorld
from .returns import in_range, static_returns


@dataclass
class World:
    """Everything a sweep can hit. Body 0 is the static scene. The scene extraction
    gives every body the same object and material tables; bodies built with their own
    tables (tests, scripts) get them joined, with per-body index offsets."""

    static: PreparedScene
    moving: list = field(default_factory=list)  # RigidBody and TimedScene

    def __post_init__(self):
        self._instanced = False  # not built yet
        geos = [b.geometry for b in self.bodies]
        base = geos[0]
        self._offsets = None
        if all(g.objects == base.objects and g.materials == base.materials for g in geos[1:]):
            self._tables = base
            return
        self._offsets = np.cumsum([[0, 0]] + [[len(g.objects) or 1, len(g.materials)]
                                              for g in geos[:-1]], axis=0).astype(np.int32)
        self._tables = SceneGeometry(np.zeros((0, 3)), np.zeros((0, 3), np.int64), [], [],
                                     [o for g in geos for o in (g.objects or [ObjectInfo("")])],
                                     [m for g in geos for m in g.materials])

    @property
    def bodies(self):
        return [self.static] + list(self.moving)

    @property
    def instanced(self):
        """The static scene and the rigidly moving bodies as one Embree traversal
        (``instancing.InstancedWorld``), or None (other backends, or nothing moves
        rigidly): built on first use."""
        if self._instanced is False:
            self._instanced = InstancedWorld.build(self.static, self.moving) \
                if self.moving else None
        return self._instanced

    def cast(self, origins, directions, times, max_range, watertight=True, order=None,
             reuse=False):
        """Nearest hit over all bodies: (dist, body index, triangle index, normals);
        ``order``: a trace order for the static scene (see ``casting.cast_exact``).
        ``reuse``: the static scene's part may come from its previous cast of the same
        rays (see ``PreparedScene.cast``); only the moving bodies are cast then."""
        return self.start(origins, directions, times, max_range, watertight, order, reuse)()

    def start(self, origins, directions, times, max_range, watertight=True, order=None,
              reuse=False):
        """``cast``, started; returns a function giving its result. With the compiled
        Embree loop the static scene (or all, as instances) is cast meanwhile, so the
        caller's own work overlaps it (see ``PreparedScene.start``); bodies cast on
        their own are cast right here."""
        rest = list(enumerate(self.moving, start=1))
        reuse = reuse and watertight and self.static.reusable(origins, directions)
        if reuse:
            # The static scene cast on its own, through its store of the last cast; the
            # moving bodies traced without it (as instances, or each on its own) and
            # merged in below: the nearer hit wins, as in one traversal.
            inst = InstancedWorld.build(self.static, self.moving, with_static=False) \
                if self.moving else None
        else:
            inst = self.instanced
        if inst is not None:
            rest = [(k, b) for k, b in rest if k not in inst.traced]
        if inst is not None and not reuse:  # the static scene among the instances
            pending = inst.start(origins, directions, times, max_range, order, watertight)
        elif not rest and inst is None:
            started = self.static.start(origins, directions, max_range, watertight, order,
                                        reuse)
            pending = lambda: _static_hits(*started())  # noqa: E731
        else:
            got = _static_hits(*self.static.cast(origins, directions, max_range, watertight,
                                                 order, reuse))
            pending = lambda: got  # noqa: E731
            if inst is not None:  # the moving bodies, as instances without the static scene
                movers = inst.start(origins, directions, times, max_range, order, True)
                pending = lambda: _nearer(got, movers())  # noqa: E731
        # Bodies cast on their own (deforming sub-steps; every body on backends that
        # cannot instance), and the objects of instanced bodies whose motion Embree's
        # steps cannot follow: their nearest hits are merged in.
        more = [(k, b.cast(origins, directions, times, max_range, watertight)) for k, b in rest]
        if inst is not None:
            more += [(k, self.moving[k - 1].cast(origins, directions, times, max_range,
                                                 watertight, objects=objs))
                     for k, objs in inst.portable.items()]
        if not more:
            return pending

        def merged():
            got = pending()
            for k, (d2, t2, n2) in more:
                got = _nearer(got, (d2, np.where(t2 >= 0, k, -1), t2, n2))
            return got

        return merged

    @property
    def geometry(self):
        """A geometry holding the object and material tables of every body (the
        indices ``surface_ids`` gives point into them)."""
        return self._tables

    def returns(self, dist, body, tri, rmin, rmax):
        """(valid, surface ids) of a cast (``cast``'s dist, body, tri): per ray, whether
        it returns a point (a hit within [rmin, rmax]) and ``surface_ids`` of what it
        hit. A static world's in one pass (``returns.static_returns``: in C where it is
        built)."""
        if not self.moving:
            return static_returns(dist, tri, self.static.geometry.surface_ids(), rmin, rmax)
        if self._offsets is None:
            # Every body's rows in one table: the same pass, each hit's row found from
            # its body's first row (a miss: -1, the table's last row, the static
            # scene's first as surface_ids gives a miss).
            table, starts = self._joined_table()
            return static_returns(dist, tri + starts[body], table, rmin, rmax)
        return in_range(dist, tri, rmin, rmax), self.surface_ids(body, tri)

    def _joined_table(self):
        """(every body's ``surface_ids`` rows one after the other, then the static
        scene's first row (or zeros); per body its first row, then 0 for body -1).
        Kept on the static scene for the same bodies' geometries (a sweep's frames)."""
        geos = [b.geometry for b in self.bodies]
        kept = getattr(self.static, "_joined_table", None)
        if kept is not None and len(kept[0]) == len(geos) \
                and all(a is b for a, b in zip(kept[0], geos)):
            return kept[1], kept[2]
        tables = [g.surface_ids() for g in geos]
        last = tables[0][:1] if len(tables[0]) else np.zeros((1, 2), np.int32)
        table = np.ascontiguousarray(np.concatenate(tables + [last]), np.int32)
        starts = np.append(np.cumsum([0] + [len(t) for t in tables[:-1]]), 0).astype(np.int64)
        self.static._joined_table = (geos, table, starts)
        return table, starts

    def surface_ids(self, body, tri):
        """(N, 2) int32 (object index, material index) of the surface each ray hit, into
        the shared tables (see ``SceneGeometry.surface_ids``); rows with no hit (body
        -1) hold arbitrary valid indices."""
        # Most rows are static: one gather for all, then the few others redone.
        # take(axis=0): numpy's fancy indexing copies rows one by one, ~8x slower.
        t = self.static.geometry.surface_ids()
        rows = np.where(body == 0, tri, 0) if self.moving else tri
        out = pair_rows(t, rows) if len(t) else np.zeros((len(tri), 2), np.int32)
        for k, b in enumerate(self.moving, start=1):
            sel = np.nonzero(body == k)[0]
            if len(sel):
                out[sel] = b.geometry.surface_ids().take(tri[sel], axis=0)
                if self._offsets is not None:
                    out[sel] += self._offsets[k]
        return out


def _static_hits(dist, tri, normals):
    """A static scene's cast as a world's: (dist, body 0 where it hit else -1, tri,
    normals)."""
    return dist, hit_body(tri), tri, normals


def _nearer(got, other):
    """Merge two (dist, body, tri, normals) casts of the same rays into ``got``: per
    ray, the nearer hit (``other``'s where it hit something closer)."""
    dist, body, tri, normals = got
    d2, b2, t2, n2 = other
    closer = (b2 >= 0) & (d2 < dist)
    dist[closer], body[closer], tri[closer], normals[closer] = \
        d2[closer], b2[closer], t2[closer], n2[closer]
    return dist, body, tri, normals

"""Ray casting on Blender's ``mathutils.bvhtree.BVHTree``.

The per-ray ``ray_cast`` call is the only Python loop in a scan; it runs through
``map`` over prepared tuples so the interpreter does as little as possible per ray.
"""

from itertools import repeat

import numpy as np


class BVHCaster:
    name = "bvhtree"

    def __init__(self, vertices, triangles):
        from mathutils.bvhtree import BVHTree

        self.tree = BVHTree.FromPolygons(
            np.asarray(vertices, dtype=np.float64).tolist(),
            np.asarray(triangles, dtype=np.int64).tolist(),
            all_triangles=True,
            epsilon=0.0,
        )

    def cast(self, origins, directions, max_dist):
        d = np.asarray(directions, dtype=np.float64)
        o = np.asarray(origins, dtype=np.float64).reshape(-1, 3)
        n = d.shape[0]
        dl = d.tolist()
        ol = repeat(tuple(o[0]), n) if o.shape[0] == 1 else o.tolist()
        res = list(map(self.tree.ray_cast, ol, dl, repeat(float(max_dist), n)))
        tri = np.fromiter((-1 if r[2] is None else r[2] for r in res), dtype=np.int64, count=n)
        dist = np.fromiter((np.inf if r[3] is None else r[3] for r in res), dtype=np.float64,
                           count=n)
        return dist, tri

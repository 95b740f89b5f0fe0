"""Every ray-casting backend and baseline built once on the same triangles and timed on
the same rays (``Backends``), and a backend that counts the rays a frame casts
(``CountingFactory``): what the devices and scaling sections measure with."""

import time

import numpy as np

from bench.baselines import bare_loop
from bench.timing import log


class Backends:
    """Every backend built once on the same sensor-centred triangles."""

    def __init__(self, geometry, origin, reach, which=("embree", "bvhtree", "open3d"),
                 prepared=True):
        import bpy  # noqa: F401  (mathutils)

        from rls_addon.core.casting import BVHCaster
        from rls_addon.core.casting.embree import EmbreeCaster
        from rls_addon.core.world.bodies import PreparedScene
        from rls_addon.core.scene.geometry import clean_for_casting

        self.origin = np.asarray(origin, float)
        self.build = {}
        self.prepared = {}
        if not prepared:
            which_prepared = ()
        else:
            which_prepared = which
        if "embree" in which_prepared:
            t = time.perf_counter()
            self.prepared["embree"] = PreparedScene(geometry, origin, reach, EmbreeCaster)
            self.build["embree (scene, incl. watertight hull)"] = time.perf_counter() - t
        if "bvhtree" in which_prepared:
            t = time.perf_counter()
            self.prepared["bvhtree"] = PreparedScene(geometry, origin, reach, BVHCaster)
            self.build["bvhtree (scene, incl. watertight hull)"] = time.perf_counter() - t
        if self.prepared:
            ref = next(iter(self.prepared.values()))
            self.vertices, self.triangles = ref.vertices, ref.triangles
        else:
            self.vertices, self.triangles, _, _ = clean_for_casting(geometry, origin, reach)
        self.casters = {}
        if "embree" in which:
            t = time.perf_counter()
            self.casters["embree"] = EmbreeCaster(self.vertices, self.triangles)
            self.build["embree"] = time.perf_counter() - t
            self.casters["embree_1t"] = EmbreeCaster(self.vertices, self.triangles, threads=1)
        if "bvhtree" in which:
            t = time.perf_counter()
            self.casters["bvhtree"] = BVHCaster(self.vertices, self.triangles)
            self.build["bvhtree"] = time.perf_counter() - t
        self.o3d = None
        if "open3d" in which:
            try:
                import open3d as o3d

                t = time.perf_counter()
                sc = o3d.t.geometry.RaycastingScene()
                sc.add_triangles(o3d.core.Tensor(self.vertices.astype(np.float32)),
                                 o3d.core.Tensor(self.triangles.astype(np.uint32)))
                sc.cast_rays(o3d.core.Tensor(np.array([[0, 0, 0, 1, 0, 0]], np.float32)))
                self.build["open3d"] = time.perf_counter() - t
                self.o3d = sc
            except ImportError:
                log("bench: open3d is not installed: no Open3D baseline")

    def cast_times(self, dirs, max_range, repeat=5):
        """Seconds to cast ``dirs`` from the sensor with each backend and baseline: the
        best of ``repeat`` rounds, backends taking turns within a round so that load
        from other work on the machine hits them alike."""
        o = np.zeros((1, 3))
        runs = {}
        for name in ("embree", "embree_1t", "bvhtree"):
            if name in self.casters:
                runs[name] = (lambda c: lambda: c.cast(o, dirs, max_range))(self.casters[name])
        if "bvhtree" in self.casters:
            runs["bare ray_cast loop"] = bare_loop(self.casters["bvhtree"].tree, dirs, max_range)
        if self.o3d is not None:
            import open3d as o3d

            def o3d_cast(threads):
                rays = np.empty((len(dirs), 6), np.float32)
                rays[:, :3] = 0.0
                rays[:, 3:] = dirs
                return self.o3d.cast_rays(o3d.core.Tensor(rays), nthreads=threads)

            runs["open3d"] = lambda: o3d_cast(0)
            runs["open3d_1t"] = lambda: o3d_cast(1)
        slow = {"bvhtree", "bare ray_cast loop"}
        out = {k: float("inf") for k in runs}
        for i in range(repeat):
            for name, fn in runs.items():
                if name in slow and i >= max(2, repeat // 2):
                    continue  # BVHTree runs are long and steadier: fewer repeats
                t = time.perf_counter()
                fn()
                out[name] = min(out[name], time.perf_counter() - t)
        return out


def CountingFactory(factory):
    """A backend wrapping ``factory`` that counts the rays every caster it built was
    asked to cast (primary rays, the watertight re-check of misses, nudged re-casts,
    ghost rays) in its class attribute ``rays``."""
    from rls_addon.core.casting import CasterBase

    class Counted(CasterBase):
        rays = 0

        def __init__(self, vertices, triangles):
            self.inner = factory(vertices, triangles)
            self.name = self.inner.name

        def cast(self, origins, directions, max_dist):
            Counted.rays += len(directions)
            return self.inner.cast(origins, directions, max_dist)
    return Counted

"""InfraLOB regions drawn in Blender: a flat mesh object whose outline in world xy
is the region of interest. Mark it with the custom property ``rls_infralob = True``."""

import numpy as np

from ..core.errors import RegionError

LOB_PROPERTY = "rls_infralob"


def is_lob(obj):
    """True when ``obj`` carries a true ``rls_infralob`` custom property."""
    try:
        return bool(obj.get(LOB_PROPERTY, False))
    except (AttributeError, TypeError):
        return False


def _boundary_loop(edges, n_faces):
    """Chain boundary edges (each a vertex pair) into one closed loop of vertex indices."""
    nbr = {}
    for a, b in edges:
        nbr.setdefault(a, []).append(b)
        nbr.setdefault(b, []).append(a)
    if any(len(v) != 2 for v in nbr.values()):
        raise RegionError("the region mesh's boundary is not a single simple loop (holes or touching corners)")
    start = min(nbr)
    loop, prev, cur = [start], None, start
    while True:
        nxt = nbr[cur][0] if nbr[cur][0] != prev else nbr[cur][1]
        if nxt == start:
            break
        loop.append(nxt)
        prev, cur = cur, nxt
        if len(loop) > len(nbr):
            raise RegionError("the region mesh's boundary does not close")
    if len(loop) != len(nbr):
        raise RegionError("the region mesh has several separate outlines; use one connected flat mesh")
    return loop


def lob_polygon_world(obj):
    """(M, 2) float64 outline of flat mesh ``obj`` in world xy (z dropped).

    A single n-gon gives its vertices in order; otherwise the boundary edges
    (used by exactly one face) are chained into a loop.
    """
    if getattr(obj, "type", None) != "MESH":
        raise RegionError(f"region object {getattr(obj, 'name', obj)!r} is not a mesh")
    shown = [m.name for m in obj.modifiers if m.show_viewport]
    if shown:
        # the outline is the mesh's own: a Mirror or Array would show a region it is not
        raise RegionError(f"region object {obj.name!r} has modifiers ({', '.join(shown)}) "
                          "that change the region it shows, but its outline is read from "
                          "its mesh without them; apply them (Object > Apply > All "
                          "Modifiers) or remove them")
    mesh = obj.data
    if len(mesh.polygons) == 0:
        raise RegionError(f"region object {obj.name!r} has no faces; fill its outline (a plane or n-gon)")
    co = np.empty(len(mesh.vertices) * 3, dtype=np.float64)
    mesh.vertices.foreach_get("co", co)
    co = co.reshape(-1, 3)
    m = np.array(obj.matrix_world, dtype=np.float64)
    world = co @ m[:3, :3].T + m[:3, 3]
    if len(mesh.polygons) == 1:
        loop = list(mesh.polygons[0].vertices)
    else:
        use = {}
        for poly in mesh.polygons:
            for key in poly.edge_keys:
                use[key] = use.get(key, 0) + 1
        loop = _boundary_loop([k for k, c in use.items() if c == 1], len(mesh.polygons))
    return world[loop, :2].copy()

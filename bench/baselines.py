"""The baselines the bench holds RLS to that are not one of its backends."""


def bare_loop(tree, dirs, max_range):
    """The bare BVHTree loop: one ``ray_cast`` per ray over prepared Python lists, the
    least any Python-driven BVHTree scan can cost (the conversion is not timed)."""
    dl = dirs.tolist()
    o = (0.0, 0.0, 0.0)
    rc = tree.ray_cast
    m = float(max_range)

    def loop():
        for d in dl:
            rc(o, d, m)
    return loop

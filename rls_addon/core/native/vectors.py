"""Row-wise vector arithmetic on (N, 3) arrays, in one fixed order of operations.

The numpy references and the compiled kernels (native/c/embree_loop.c, points.c,
edges.c, ghosts.c) sum a dot product left to right, ((x0 y0 + x1 y1) + x2 y2), so
both give the same bits. numpy's einsum sums in an order of its own build's choosing
((x0 y0 + x2 y2) + x1 y1 on the project's machine), so the references use this."""


def row_dot(a, b):
    """Dot products of the rows of ``a`` and ``b`` ((N, 3), or broadcasting to it),
    summed left to right."""
    return a[:, 0] * b[:, 0] + a[:, 1] * b[:, 1] + a[:, 2] * b[:, 2]

"""Counting points in the same disks again and again: a study counts every candidate's
points in one fixed set of disks, so what depends on the disks alone is worked out once.

``DiskCounter(centres, radius)`` lays a grid of square cells of ``radius /
CELLS_PER_RADIUS`` over the disks and sorts each disk's cells into three kinds, once:

- *inside*: every point of the cell is within the radius (its farthest corner is, with a
  margin for rounding). In a row of the grid a disk's inside cells are one run of
  columns, kept as the run's first cell and the cell after its last (``span_lo``,
  ``span_hi``): its points are counted from a prefix sum of the points per cell, two
  look-ups per row of the disk, however many points;
- *edge*: the circle crosses the cell: its points are tested one by one, with the very
  comparison of ``metrics.count_in_disks`` (dx * dx + dy * dy <= r * r). The edge
  cells are kept per cell (``edge_start``, ``edge_count``, ``edge_disk``: the disks
  whose circle crosses each cell), so a point goes straight to the disks it must be
  tested against;
- out: no point of the cell can be within the radius: nothing to do.

Per call (``counts(xy)``): the points' cells, one bincount and its prefix sum, two
gathers per (disk, row) for the inside runs, and the exact tests of each point in an
edge cell. The counts are those of ``metrics.count_in_disks`` (the reference) and of a
brute-force test of every (point, disk) pair, integer for integer
(tests/core/test_disk_counter.py). For the bench study (10k points in the region,
6,000 disks of 0.7 m) a candidate's counts take about 1.2 ms, against 3.5 ms with the
inside / edge cells listed one by one and 15 ms with the reference
(bench/study_costs.py).

A point is one complex number x + iy in the per-pair work: numpy is several times
slower on (n, 2) arrays than on (n,) ones, and a complex difference is the two float
differences, the same bits.

``counts`` runs in C (``native/c/disks.c``, in RLS's compiled library)
where that library is built: about 0.3 ms for the bench study's candidate against
0.8-1.2 ms in numpy (10k points, 6,000 disks, measured alone); the numpy
``counts_numpy`` above is the reference it follows step by step, and the tests hold the
two to the same counts (tests/core/test_disk_counter.py).
"""

import ctypes
import threading

import numpy as np

from ..native.kernels import Kernel
from .polygon import grid_cells

CELLS_PER_RADIUS = 4  # 3 to 5 measure alike (bench study: 10k points, 6,000 disks of 0.7 m)
# The grid's tables (a prefix sum, an edge count and start per cell) are not worth their
# memory beyond this many cells: larger cells, and past cells of the radius' size the
# reference counts.
MAX_CELLS = 4_000_000


class DiskCounter:
    def __init__(self, centres, radius, cells_per_radius=CELLS_PER_RADIUS):
        self.centres = np.ascontiguousarray(np.asarray(centres, dtype=np.float64).reshape(-1, 2))
        self.centre_z = np.empty(len(self.centres), np.complex128)  # cx + i cy
        self.centre_z.real, self.centre_z.imag = self.centres[:, 0], self.centres[:, 1]
        self.radius = r = float(radius)
        n = len(self.centres)
        # Coarser cells rather than none for a large region; no grid at all (the
        # reference counts) beyond MAX_CELLS of the radius' size
        for k in range(int(cells_per_radius), 0, -1):
            self.k, self.h = k, r / k
            h = self.h
            # k + 3 cells of margin around the disks' box: the cells of the outer ring
            # (where points beyond the grid are clamped) are farther than the radius from
            # every centre, and no disk's cells reach them
            self.lo = lo = (self.centres.min(axis=0) - r - 3 * h) if n else np.zeros(2)
            hi = self.centres.max(axis=0) if n else np.zeros(2)
            self.nx, self.ny = (int(v) + k + 4 for v in np.ceil((hi - lo) / h))
            if self.nx * self.ny <= MAX_CELLS:
                break
        self.usable = n > 0 and self.nx * self.ny <= MAX_CELLS
        self._lock, self._before, self._cell = threading.Lock(), None, None  # C scratch
        if self.usable:
            self._classify()

    def __getstate__(self):  # sent to other processes without the lock and scratch
        return dict(self.__dict__, _lock=None, _before=None, _cell=None)

    def __setstate__(self, state):
        self.__dict__.update(state, _lock=threading.Lock())

    def _classify(self):
        r, h, k, lo, c = self.radius, self.h, self.k, self.lo, self.centres
        far_end = lo + h * np.array([self.nx, self.ny])
        slack = 1e-9 * max(1.0, r, float(np.abs(lo).max()), float(np.abs(far_end).max()))
        home = np.floor((c - lo) / h).astype(np.int64)          # (D, 2) the centre's cell
        off = np.arange(-k - 1, k + 2)                          # (W,) cells around it
        ix = home[:, :1] + off                                  # (D, W) columns
        iy = home[:, 1:] + off                                  # (D, W) rows
        assert ix.min() >= 1 and iy.min() >= 1 and ix.max() < self.nx - 1 \
            and iy.max() < self.ny - 1

        def nearest_farthest(i, cen):
            """Per axis, the nearest and the farthest distance from the centre to a
            cell's extent, squared."""
            x0 = lo[i] + (ix if i == 0 else iy) * h
            near = np.maximum(0.0, np.maximum(x0 - cen, cen - (x0 + h)))
            far = np.maximum(np.abs(x0 - cen), np.abs(x0 + h - cen))
            return near * near, far * far

        near_x, far_x = nearest_farthest(0, c[:, :1])
        near_y, far_y = nearest_farthest(1, c[:, 1:])
        # (D, rows, columns); a row's inside cells are one run (the farthest corner's
        # distance falls then rises along a row)
        inside = far_y[:, :, None] + far_x[:, None, :] <= max(r - slack, 0.0) ** 2
        edge = ~inside & (near_y[:, :, None] + near_x[:, None, :] <= (r + slack) ** 2)
        run = inside.sum(axis=2)                                # (D, W) inside cells per row
        first = ix[np.arange(len(c))[:, None], np.argmax(inside, axis=2)]
        rows = np.flatnonzero(run.any(axis=0))                  # rows some disk has a run in
        base = iy[:, rows] * self.nx + np.where(run[:, rows] > 0, first[:, rows], 0)
        # (rows, D), row by row: a disk's inside count is the sum down a column
        self.span_lo = np.ascontiguousarray(base.T)
        self.span_hi = np.ascontiguousarray((base + run[:, rows]).T)
        # the edge cells, grouped by cell: edge_disk[edge_start[i]:edge_start[i + 1]]
        # are the disks whose circle crosses cell i
        cell = (iy[:, :, None] * self.nx + ix[:, None, :])[edge]
        disk = np.broadcast_to(np.arange(len(c))[:, None, None], edge.shape)[edge]
        order = np.argsort(cell, kind="stable")
        self.edge_disk = disk[order].astype(np.int64)
        per_cell = np.bincount(cell, minlength=self.nx * self.ny).astype(np.int64)
        self.edge_count = per_cell
        self.edge_start = np.cumsum(per_cell) - per_cell

    def counts(self, xy):
        """Points of ``xy`` within the radius (inclusive) of each centre: in C where it
        is built, else ``counts_numpy`` (the same counts)."""
        from .infra import count_in_disks

        xy = np.ascontiguousarray(xy, dtype=np.float64).reshape(-1, 2)
        if not self.usable:
            return count_in_disks(xy, self.centres, self.radius)
        fn = KERNEL.get() if compiled else None
        return self.counts_numpy(xy) if fn is None else self._counts_native(fn, xy)

    def _counts_native(self, fn, xy):
        out = np.zeros(len(self.centres), dtype=np.int64)
        if len(xy) == 0:
            return out
        with self._lock:  # the scratch arrays are the counter's: one call at a time
            # kept between calls: fresh arrays of this size cost more in page faults
            # than the counting (the C code clears the prefix sum)
            if self._before is None:
                self._before = np.empty(self.nx * self.ny + 1, np.int64)
            if self._cell is None or len(self._cell) < len(xy):  # grows to the largest
                self._cell = np.empty(len(xy), np.int64)
            self._call(fn, xy, self._cell, self._before, out)
        return out

    def _call(self, fn, xy, cell, before, out):
        args = _DisksArgs(len(xy), xy.ctypes.data, float(self.lo[0]), float(self.lo[1]),
                          float(self.h), self.nx, self.ny, len(self.centres),
                          self.span_lo.shape[0], self.span_lo.ctypes.data,
                          self.span_hi.ctypes.data, self.edge_start.ctypes.data,
                          self.edge_count.ctypes.data, self.edge_disk.ctypes.data,
                          self.centres.ctypes.data, self.radius * self.radius,
                          cell.ctypes.data, before.ctypes.data, out.ctypes.data)
        fn(ctypes.byref(args))

    def counts_numpy(self, xy):
        """The reference of ``counts`` (``xy``: (N, 2) float64, contiguous), in numpy."""
        out = np.zeros(len(self.centres), dtype=np.int64)
        if len(xy) == 0:
            return out
        # x + iy: one element per point for the repeats and differences below (numpy's
        # complex subtraction is the two float subtractions, the same bits)
        z = xy.view(np.complex128).ravel()
        # beyond the grid (or not finite): into the outer ring, which no disk reaches
        cell = grid_cells(z.real, z.imag, self.lo, self.h, self.nx, self.ny)
        # inside runs: the points in cells [lo, hi) of a row, from the prefix sum per cell
        before = np.zeros(self.nx * self.ny + 1, np.int64)
        np.cumsum(np.bincount(cell, minlength=self.nx * self.ny), out=before[1:])
        out += (before[self.span_hi] - before[self.span_lo]).sum(axis=0)
        # edge cells: each point against the disks whose circle crosses its cell
        n_edge = self.edge_count[cell]
        ends = np.cumsum(n_edge)
        total = int(ends[-1])
        if total == 0:
            return out
        at = np.repeat(self.edge_start[cell] - (ends - n_edge), n_edge)
        at += np.arange(total)
        who = self.edge_disk[at]                   # (pairs,) the disk of each test
        d = np.repeat(z, n_edge)
        d -= self.centre_z[who]                    # (dx, dy) of each pair
        dx, dy = d.real, d.imag
        hit = dx * dx + dy * dy <= self.radius * self.radius  # as count_in_disks
        out += np.bincount(np.compress(hit, who), minlength=len(out))
        return out


class _DisksArgs(ctypes.Structure):
    """``disks_t`` of native/c/disks.c."""

    _fields_ = [("n", ctypes.c_int64), ("xy", ctypes.c_void_p), ("lo_x", ctypes.c_double),
                ("lo_y", ctypes.c_double), ("h", ctypes.c_double), ("nx", ctypes.c_int64),
                ("ny", ctypes.c_int64), ("disks", ctypes.c_int64), ("rows", ctypes.c_int64),
                ("span_lo", ctypes.c_void_p), ("span_hi", ctypes.c_void_p),
                ("edge_start", ctypes.c_void_p), ("edge_count", ctypes.c_void_p),
                ("edge_disk", ctypes.c_void_p), ("centres", ctypes.c_void_p),
                ("r2", ctypes.c_double), ("cell", ctypes.c_void_p),
                ("before", ctypes.c_void_p), ("out", ctypes.c_void_p)]


NATIVE_DISKS_ABI = 1
# Off: every candidate is counted in numpy (the reference the C code is tested against).
compiled = True
KERNEL = Kernel("rls_disk_counts", "rls_disks_abi", NATIVE_DISKS_ABI,
                [ctypes.POINTER(_DisksArgs)])

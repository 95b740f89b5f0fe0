"""The background of a still roadside LiDAR, per cell of its own range image, as deployed
roadside systems keep it, and the foreground of a frame against it.

A *cell* is (channel, azimuth bin) of the sensor's range image: the channel is the
point's ``ring`` when the points carry one, else the device's ring found from the distinct
elevations of the learning frames (fixed ``elevation_res_deg`` bins for a pattern without
rings, such as a Risley prism's); the azimuth bin is ``azimuth_res_deg`` wide, by default
the device's own azimuth step measured from the learning frames, centred per row on where
the row fires. A still sensor fires the same rays every sweep, so one cell sees one
surface (or two, across a depth edge or where a glossy facade turns some of its returns
into ghosts) frame after frame.

Only what a real device reports is read: x, y, z (sensor frame) and ring. Labels,
instances and ghost flags are ground truth and are never looked at.

Learning (``BackgroundModel.learn``): every return of every learning frame is put in its
cell; a cell's ranges, sorted, are cut into *modes* wherever two neighbours are more than
``margin`` apart; a mode's support is the share of frames it was seen in, and "no return"
is a mode at infinity. Traffic is nearer than what it passes in front of, so:

- the farthest mode seen in at least ``min_support`` (10%) of the frames is background;
- a nearer mode is background when seen in at least ``steady_support`` (90%) of them (a
  pole, a parked car), or in at least ``persist_support`` (30%) *coming and going*: a
  glossy facade's glass and ghost flip from frame to frame (about half each), while a
  car that stood at a red light and left is one long run of frames (a run test,
  ``_background_modes``) and cars that drive through a cell are there for a few frames
  each (under 30% in the busy sample below);
- up to ``max_modes`` (3) modes per cell are kept, the best supported first.

A few traffic-free frames make a background too (every return is in all of them); one
frame cannot tell a glossy facade's glass from its ghost. A car that stood through more
than 90% of the learning frames becomes background, as it does in deployed systems.

Foreground (``BackgroundModel.foreground``): a return is foreground when it is nearer than
every background mode of its cell by ``margin`` (nearer than the nearest mode's nearest
learned range, minus the margin). The margin is ``max(min_margin, k_sigma * noise_sigma)``:
with RLS's presets (2-3 cm noise) the 0.3 m floor decides, which is what real deployments
use against beam jitter and calibration drift, and what keeps a flat road at grazing
incidence from flickering; a noisier device (a sigma above 6 cm) gets 5 sigma. Returns
farther than the background (through a window, a ghost beyond its glass) are never
foreground. A foreground pixel with fewer than 2 foreground neighbours in the range image
is dropped: objects are patches, a cell that was unlucky while learning is alone.

A cell that never had a background return (sky, beyond the end of the road, past the
device's range) cannot say what is in front of its background. A return there is only
*possibly* foreground; ``RoadsideDetector`` keeps it when it is plausibly an object: its
world height above the ground near it is within an object's (``[-0.3, max_height]``) and
it is within ``max_range`` of the sensor; DBSCAN's density then decides, as for every
foreground point. So a car coming over the end of the road is found, while a bird, an
insect on the window, or a false return from fog high above the road is not.
"""

import numpy as np

from ...errors import InputError

DEFAULT_AZIMUTH_RES_DEG = 0.2
DEFAULT_ELEVATION_RES_DEG = 0.1


def sensor_xyz_ring(points):
    """((N, 3) float64 sensor-frame x y z, (N,) int64 ring or None) of ``points``: a
    structured array with x, y, z (and ring), or an (N, >=3) array (x y z ...). Nothing
    else of the record is read (never label, instance or ghost)."""
    if points is None:
        return np.zeros((0, 3)), None
    arr = np.asarray(points)
    if arr.dtype.names:
        missing = [f for f in ("x", "y", "z") if f not in arr.dtype.names]
        if missing:
            raise InputError(f"points have no field(s) {', '.join(missing)}")
        xyz = np.empty((len(arr), 3))
        xyz[:, 0], xyz[:, 1], xyz[:, 2] = arr["x"], arr["y"], arr["z"]
        ring = arr["ring"].astype(np.int64) if "ring" in arr.dtype.names else None
        return xyz, ring
    arr = np.asarray(arr, np.float64)
    if arr.size == 0:
        return np.zeros((0, 3)), None
    if arr.ndim != 2 or arr.shape[1] < 3:
        raise InputError(f"points must be a structured array or (N, >=3); got shape {arr.shape}")
    return np.ascontiguousarray(arr[:, :3]), None


class RangeImageGrid:
    """Cells of a sensor's range image: rows are channels (``ring``) or elevation bins,
    columns azimuth bins centred on where the device fires in each row (``phase``, in
    bins, measured at learning)."""

    def __init__(self, azimuth_res_deg, use_ring, elevation_res_deg, rows, phase):
        self.azimuth_res = float(np.radians(azimuth_res_deg))
        self.columns = int(round(2 * np.pi / self.azimuth_res))
        self.azimuth_res = 2 * np.pi / self.columns  # a whole number of columns
        self.use_ring = bool(use_ring)
        self.elevation_res = float(np.radians(elevation_res_deg))
        self.rows = int(rows)
        self.phase = np.asarray(phase, np.float64)  # (rows,) fraction of a column
        self.row_rank = np.full(self.rows, -1, np.int64)  # rows by elevation, seen ones

    @property
    def cells(self):
        return self.rows * self.columns

    elevation_edges = None  # (rows - 1,) radians between the rings found by elevation

    def row_of(self, xyz, ring):
        if self.use_ring:
            if ring is None:
                raise InputError("the background was learned by ring: these points have none")
            return ring
        el = np.arctan2(xyz[:, 2], np.hypot(xyz[:, 0], xyz[:, 1]))
        if self.elevation_edges is not None:
            return np.searchsorted(self.elevation_edges, el).astype(np.int64)
        return np.floor((el + np.pi / 2) / self.elevation_res).astype(np.int64)

    def cell_of(self, xyz, ring):
        """(N,) cell index of each point; -1 for a row the grid does not have."""
        row = self.row_of(xyz, ring)
        ok = (row >= 0) & (row < self.rows)
        rr = np.where(ok, row, 0)
        az = np.arctan2(xyz[:, 1], xyz[:, 0])
        col = np.floor(az / self.azimuth_res - self.phase[rr] + 0.5).astype(np.int64)
        col %= self.columns
        return np.where(ok, rr * self.columns + col, -1)

    def has_neighbours(self, cell, mask, least):
        """(N,) bool: the pixel of each point (``cell``) has at least ``least`` of its 8
        neighbours (rings by elevation rank, columns with the wrap at 360 degrees) holding
        a point with ``mask``. Points in rows never seen while learning count as having
        them (nothing to judge by)."""
        cell = np.asarray(cell, np.int64)
        ok = cell >= 0
        row = np.where(ok, cell // self.columns, 0)
        rank = np.where(ok, self.row_rank[row], -1)
        col = np.where(ok, cell % self.columns, 0)
        known = rank >= 0
        ranks = int(self.row_rank.max()) + 1 if len(self.row_rank) else 0
        if not known.any() or ranks == 0:
            return np.ones(len(cell), bool)
        image = np.zeros((ranks + 2, self.columns), bool)
        on = known & mask
        image[rank[on] + 1, col[on]] = True
        count = np.zeros(image.shape, np.int8)
        for dr in (-1, 0, 1):
            shifted = np.roll(image, dr, axis=0)
            for dc in (-1, 0, 1):
                if dr or dc:
                    count += np.roll(shifted, dc, axis=1)
        out = np.ones(len(cell), bool)
        out[known] = count[rank[known] + 1, col[known]] >= least
        return out

    def pixel_of(self, cell):
        """(N,) int64 (elevation rank << 32 | column) of cells (-1 for -1 and for rows
        never seen while learning): neighbouring rings of the device have neighbouring
        ranks, whatever its ring numbering."""
        cell = np.asarray(cell, np.int64)
        ok = cell >= 0
        row, col = np.where(ok, cell // self.columns, 0), np.where(ok, cell % self.columns, 0)
        rank = self.row_rank[row]
        return np.where(ok & (rank >= 0), (rank << 32) | col, -1)

    @classmethod
    def from_points(cls, samples, azimuth_res_deg=None, elevation_res_deg=None):
        """A grid fitted to sensor-frame ``samples`` [(xyz, ring)]: rows by ring when all
        have one; the azimuth step is the median step between neighbouring returns of a
        row (the device's firing step) unless given; each row's phase is the circular mean
        of where its returns fall within a column."""
        use_ring = all(r is not None for _, r in samples) and len(samples) > 0
        el_res = DEFAULT_ELEVATION_RES_DEG if elevation_res_deg is None else elevation_res_deg
        xyz = np.concatenate([x for x, _ in samples]) if samples else np.zeros((0, 3))
        edges = None
        if use_ring:
            row = np.concatenate([r for _, r in samples])
        else:
            el = np.arctan2(xyz[:, 2], np.hypot(xyz[:, 0], xyz[:, 1]))
            edges = _ring_edges(el) if elevation_res_deg is None else None
            if edges is not None:
                row = np.searchsorted(edges, el).astype(np.int64)
            else:
                row = np.floor((el + np.pi / 2) / np.radians(el_res)).astype(np.int64)
        rows = int(row.max()) + 1 if len(row) else 1
        az = np.arctan2(xyz[:, 1], xyz[:, 0])
        if azimuth_res_deg is None:
            azimuth_res_deg = _azimuth_step_deg(row, az)
        grid = cls(azimuth_res_deg, use_ring, el_res, rows, np.zeros(rows))
        grid.elevation_edges = edges
        # phase per row: where in a column the row's returns fall (circular mean)
        frac = az / grid.azimuth_res
        ang = 2 * np.pi * (frac - np.floor(frac))
        c = np.bincount(row, np.cos(ang), minlength=rows)
        s = np.bincount(row, np.sin(ang), minlength=rows)
        grid.phase = np.where(np.hypot(c, s) > 0, np.arctan2(s, c) / (2 * np.pi), 0.0)
        # rows ranked by their mean elevation (rows without returns: -1)
        el = np.arctan2(xyz[:, 2], np.hypot(xyz[:, 0], xyz[:, 1]))
        n = np.bincount(row, minlength=rows)
        mean_el = np.bincount(row, el, minlength=rows) / np.maximum(n, 1)
        seen = np.flatnonzero(n > 0)
        order = seen[np.argsort(mean_el[seen], kind="stable")]
        grid.row_rank[order] = np.arange(len(order))
        return grid


def _ring_edges(el, min_gap=1e-4, max_rings=2048):
    """Points without a ring field: the device's rings found as the distinct elevations
    of the learning frames (a spinning device fires each channel at one elevation; float32
    coordinates blur it by about 1e-7 rad), cut halfway between neighbours more than
    ``min_gap`` rad apart. None when there are no such rings (a Risley or MEMS pattern
    sweeps elevations continuously): then rows are fixed elevation bins."""
    if len(el) < 2:
        return None
    u = np.unique(np.round(el, 6))
    gap = np.diff(u)
    cut = np.flatnonzero(gap > min_gap)
    if len(cut) + 1 > max_rings or len(cut) == 0:
        return None
    return (u[cut] + u[cut + 1]) / 2


def _azimuth_step_deg(row, az):
    """The device's azimuth step: the median gap between a row's neighbouring returns
    (distinct azimuths), over all rows; the default when there are too few returns."""
    if len(az) < 16:
        return DEFAULT_AZIMUTH_RES_DEG
    order = np.lexsort((az, row))
    r, a = row[order], az[order]
    gap = np.diff(a)
    gap = gap[(np.diff(r) == 0) & (gap > 1e-6)]
    if len(gap) < 8:
        return DEFAULT_AZIMUTH_RES_DEG
    step = float(np.degrees(np.median(gap)))
    return min(max(step, 0.01), 5.0)


def _background_modes(m_cell, m_support, m_longest, n_frames, empty, min_support,
                      persist_support, steady_support, alpha=0.01):
    """(M,) bool: which modes (sorted by cell, then range) are background.

    - The farthest mode of a cell seen in at least ``min_support`` of the frames is (a
      cell that returned nothing that often has its farthest mode at infinity, and then
      no finite farthest mode).
    - A nearer mode is when it was there in at least ``steady_support`` of the frames, or
      in at least ``persist_support`` of them *coming and going*: a glossy facade's glass
      and ghost flip from frame to frame, while a car that stood and left is one long
      run of frames (the cars that later drive over its spot add only short ones). A
      mode stood when its longest run ``L`` is one that flips independent from frame to
      frame with its support ``p`` would hardly make: ``n (1 - p) p^L < alpha`` over
      ``n`` frames (1%: with 100 frames, 12 frames at p = 0.5, 16 at p = 0.6; with 10
      frames, no run of a half-supported mode is long enough)."""
    idx = np.arange(len(m_cell))
    qual = m_support >= min_support - 1e-12
    last = np.full(len(empty), -1, np.int64)
    np.maximum.at(last, m_cell[qual], idx[qual])
    farthest = (idx == last[m_cell]) & (empty[m_cell] < min_support - 1e-12)
    steady = m_support >= min(steady_support, 1.0) - 1e-12
    p = np.clip(m_support, 1e-12, 1 - 1e-12)
    chance = n_frames * (1 - p) * np.exp(m_longest * np.log(p))
    stood = chance < alpha
    flips = (m_support >= min(persist_support, 1.0) - 1e-12) & ~stood
    return farthest | steady | flips


class BackgroundModel:
    """The background of one still sensor (see the module docstring).

    near     (cells,) float64: the nearest learned range of the cell's nearest background
             mode (m); +inf for a cell without one
    modes    (cells, max_modes) float64: each kept mode's median range, by support (NaN
             where fewer modes)
    support  (cells, max_modes) float64: share of learning frames each mode was seen in
    margin   the foreground margin (m)
    points   (M, 3) float64: a learned return (sensor frame) at the near edge of each kept
             mode"""

    def __init__(self, grid, near, modes, support, margin, frames, points):
        self.grid, self.near, self.modes, self.support = grid, near, modes, support
        self.margin, self.frames = float(margin), int(frames)
        self.points = points

    @classmethod
    def learn(cls, frames, margin=0.3, min_support=0.1, persist_support=0.3,
              steady_support=0.9, max_modes=3, azimuth_res_deg=None, elevation_res_deg=None):
        """The background of sensor-frame ``frames`` (a list of point arrays, see
        ``sensor_xyz_ring``), all from the same still sensor."""
        samples = [sensor_xyz_ring(f) for f in frames]
        if not samples:
            raise InputError("learning a background needs at least one frame")
        grid = RangeImageGrid.from_points(samples, azimuth_res_deg, elevation_res_deg)
        cells, rngs, frame_of = [], [], []
        for k, (xyz, ring) in enumerate(samples):
            cell = grid.cell_of(xyz, ring)
            cell[~np.isfinite(xyz).all(axis=1)] = -1
            cells.append(cell)
            rngs.append(np.linalg.norm(xyz, axis=1))
            frame_of.append(np.full(len(xyz), k, np.int64))
        all_xyz = np.concatenate([x for x, _ in samples])
        cell, rng, frm = (np.concatenate(cells), np.concatenate(rngs),
                          np.concatenate(frame_of))
        ok = cell >= 0
        index = np.flatnonzero(ok)
        cell, rng, frm = cell[ok], rng[ok], frm[ok]
        n_frames = len(samples)
        near = np.full(grid.cells, np.inf)
        modes = np.full((grid.cells, max_modes), np.nan)
        support = np.zeros((grid.cells, max_modes))
        points = np.zeros((0, 3))
        if len(cell):
            order = np.lexsort((rng, cell))
            cell, rng, frm, index = cell[order], rng[order], frm[order], index[order]
            # a new mode wherever the cell changes or the range jumps by more than the margin
            new = np.ones(len(cell), bool)
            new[1:] = (cell[1:] != cell[:-1]) | (rng[1:] - rng[:-1] > margin)
            mode_id = np.cumsum(new) - 1
            starts = np.flatnonzero(new)
            m_cell = cell[starts]
            m_near = rng[starts]
            m_index = index[starts]
            m_count = np.diff(np.r_[starts, len(cell)])
            m_median = rng[starts + (m_count - 1) // 2]
            # support: distinct frames per mode (two rays of one frame in a cell count once)
            pair = np.unique(mode_id * n_frames + frm)
            p_mode, p_frame = pair // n_frames, pair % n_frames
            m_frames = np.bincount(p_mode, minlength=len(starts))
            m_support = m_frames / n_frames
            # runs: unbroken stretches of frames a mode was seen in
            run_start = np.ones(len(pair), bool)
            run_start[1:] = (p_mode[1:] != p_mode[:-1]) | (p_frame[1:] - p_frame[:-1] > 1)
            run_id = np.cumsum(run_start) - 1
            run_len = np.bincount(run_id)
            m_longest = np.zeros(len(starts), np.int64)
            np.maximum.at(m_longest, p_mode[run_start], run_len)
            # the share of frames in which a cell returned nothing: a mode at infinity
            seen = np.unique(cell * n_frames + frm) // n_frames
            empty = 1.0 - np.bincount(seen, minlength=grid.cells) / n_frames
            keep = _background_modes(m_cell, m_support, m_longest, n_frames, empty,
                                     min_support, persist_support, steady_support)
            m_cell, m_near, m_median, m_support, m_index = (
                m_cell[keep], m_near[keep], m_median[keep], m_support[keep], m_index[keep])
            # up to max_modes per cell, the best supported (then the nearest) first
            order = np.lexsort((m_near, -m_support, m_cell))
            m_cell, m_near, m_median, m_support, m_index = (
                m_cell[order], m_near[order], m_median[order], m_support[order],
                m_index[order])
            first = np.ones(len(m_cell), bool)
            first[1:] = m_cell[1:] != m_cell[:-1]
            rank = np.arange(len(m_cell)) - np.maximum.accumulate(
                np.where(first, np.arange(len(m_cell)), 0))
            top = rank < max_modes
            modes[m_cell[top], rank[top]] = m_median[top]
            support[m_cell[top], rank[top]] = m_support[top]
            np.minimum.at(near, m_cell[top], m_near[top])
            points = all_xyz[m_index[top]]
        return cls(grid, near, modes, support, margin, n_frames, points)

    def foreground(self, points, min_neighbours=2):
        """((N,) bool: nearer than every background mode of its cell by the margin,
        (N,) bool: in a cell without background (to be judged by where it is),
        (N, 3) sensor-frame xyz, (N,) int64 cell (-1: a row the grid does not have)) of
        a frame's ``points``. Both kinds are kept only where at least ``min_neighbours``
        of the 8 neighbouring pixels of the range image hold one too: an object is a
        patch of pixels, while a cell that was unlucky while learning (a glass mode seen
        in fewer than ``persist_support`` of the frames by chance) is alone."""
        xyz, ring = sensor_xyz_ring(points)
        if not len(xyz):
            return np.zeros(0, bool), np.zeros(0, bool), xyz, np.zeros(0, np.int64)
        cell = self.grid.cell_of(xyz, ring)
        known = cell >= 0
        near = np.full(len(xyz), np.inf)
        near[known] = self.near[cell[known]]
        rng = np.linalg.norm(xyz, axis=1)
        empty = ~np.isfinite(near)
        fg = (~empty) & (rng < near - self.margin)
        if min_neighbours > 0:
            alone = ~self.grid.has_neighbours(cell, fg | empty, min_neighbours)
            fg &= ~alone
            empty &= ~alone
        return fg, empty, xyz, cell

    def background_xyz(self):
        """(M, 3) sensor-frame points: for every cell, the learned return at the near
        edge of each kept background mode (what the ground under the scene is read from)."""
        return self.points

"""When a live LiDAR is rescanned (``LiveScheduler``): changes are noted as they come
(a LiDAR moved, turned, retargeted, its preset changed, the frame changed), a rescan
starts only once its LiDAR has been still for the debounce time, a change that arrives
while a LiDAR's rescan is under way or waiting to be shown supersedes that rescan (its
result is dropped, the LiDAR scanned again once still), and the results are shown
together when nothing is left to scan. An update whose work (its scans and the
showing: the time it holds Blender) takes longer than the budget counts a strike;
``strikes`` in a row (the first update, which prepares the scene, is not counted) and
the scene is too heavy to follow live: the scheduler falls back to on demand and says
so.

The scheduler never waits, scans or draws by itself: the caller calls ``changed`` from
its change handler (cheap) and ``tick`` from a timer, which does at most one scan (or
one showing) and returns when it wants to be called again. The clock and the scanner
are handed in, so tests drive it with fakes:

    scanner.scan(key) -> data      rescan one LiDAR (its cloud)
    scanner.publish({key: data})   show the rescanned LiDARs and the region's numbers
"""

import dataclasses
import time

LIVE = "live"
ON_DEMAND = "on_demand"


@dataclasses.dataclass
class LiveSettings:
    debounce_s: float = 0.04  # how long a LiDAR is still before it is rescanned
    budget_s: float = 0.15    # the longest an update may hold Blender (scans, showing)
    strikes: int = 2          # over-budget updates in a row before on demand


@dataclasses.dataclass
class Update:
    """What one shown update cost."""

    keys: tuple          # the LiDARs rescanned
    scans: int           # scans spent on it (superseded ones included)
    work_s: float        # scanning and showing
    latency_s: float     # from the last change to the update shown
    scan_s: float = 0.0  # of the work: scanning
    publish_s: float = 0.0  # of the work: showing


class LiveScheduler:
    def __init__(self, scanner, clock=time.perf_counter, settings=None):
        self.scanner, self.clock = scanner, clock
        self.settings = settings or LiveSettings()
        self.mode = LIVE
        self.reason = ""          # why the scheduler is on demand
        self.scans = 0            # every scan made
        self.superseded = 0       # scans whose result a newer change dropped
        self.updates = []         # every Update shown
        self._generation = {}     # key -> changes seen
        self._pending = {}        # key -> time of its last change, not scanned since
        self._ready = {}          # key -> data scanned, not shown yet
        self._last_change = None
        self._scans_since = 0     # scans since the last update was shown
        self._work = 0.0          # work since the last update was shown
        self._strikes = 0

    # -- what the change handler calls -------------------------------------------------

    def changed(self, keys):
        """These LiDARs changed now: each is rescanned once it has been still for the
        debounce time; a result of theirs not shown yet is dropped."""
        now = self.clock()
        for key in keys:
            self._generation[key] = self._generation.get(key, 0) + 1
            self._pending[key] = now
            if self._ready.pop(key, None) is not None:
                self.superseded += 1
        if keys:
            self._last_change = now

    def unchanged(self, keys):
        """These LiDARs are back as they were when last shown (a change undone, a frame
        visited and left by a scan's own sub-frame sampling): nothing to rescan, and a
        result of theirs not shown yet is dropped."""
        for key in keys:
            self._generation[key] = self._generation.get(key, 0) + 1
            self._pending.pop(key, None)
            if self._ready.pop(key, None) is not None:
                self.superseded += 1

    def forget(self, key):
        """A LiDAR is gone: nothing of it is scanned or shown any more."""
        self._pending.pop(key, None)
        self._ready.pop(key, None)
        self._generation.pop(key, None)

    @property
    def busy(self):
        """Changes not shown yet."""
        return bool(self._pending or self._ready)

    # -- what the timer calls ----------------------------------------------------------

    def tick(self):
        """Do at most one step (scan one still LiDAR, or show what was scanned); returns
        the seconds until the next call is wanted (0: at once), None when idle."""
        if self.mode != LIVE:
            return None
        now = self.clock()
        debounce = self.settings.debounce_s
        # (a nanosecond's slack: a timer called back after exactly the wait asked for
        # may find a hair less by floating point, and would ask for a zero wait forever)
        still = [k for k, t in self._pending.items() if now - t >= debounce - 1e-9]
        if still:
            self._scan(min(still, key=self._pending.get))
            return 0.0
        if self._pending:
            return max(0.0, min(t + debounce - now for t in self._pending.values()))
        if self._ready:
            self._publish()
        return None

    def update_now(self):
        """Scan every LiDAR with a change and show them, still or not, live or on demand
        (the panel's Update button); returns the ``Update`` or None."""
        for key in sorted(self._pending):
            self._scan(key)
        return self._publish() if self._ready else None

    def resume(self):
        """Back to live after on demand (strikes cleared, the next update is a warm-up
        again); pending changes are scanned at the next ticks."""
        self.mode, self.reason, self._strikes = LIVE, "", 0

    # -- steps --------------------------------------------------------------------------

    def _scan(self, key):
        generation = self._generation.get(key, 0)
        t = self.clock()
        data = self.scanner.scan(key)
        self._work += self.clock() - t
        self.scans += 1
        self._scans_since += 1
        if self._generation.get(key, 0) != generation:  # changed while it was scanned
            self.superseded += 1
            return
        self._pending.pop(key, None)
        self._ready[key] = data

    def _publish(self):
        ready, self._ready = self._ready, {}
        t = self.clock()
        self.scanner.publish(ready)
        end = self.clock()
        scan_s = self._work
        self._work += end - t
        update = Update(tuple(sorted(ready)), self._scans_since, self._work,
                        end - (self._last_change if self._last_change is not None else t),
                        scan_s, end - t)
        self.updates.append(update)
        self._scans_since, self._work = 0, 0.0
        self._judge(update)
        return update

    def _judge(self, update):
        """Count a strike for an update over the budget (not the first: it prepares the
        scene); on demand after ``strikes`` in a row."""
        s = self.settings
        if len(self.updates) == 1 or self.mode != LIVE:
            return
        if update.work_s <= s.budget_s:
            self._strikes = 0
            return
        self._strikes += 1
        if self._strikes >= s.strikes:
            self.mode = ON_DEMAND
            self.reason = (f"an update takes {1000 * update.work_s:.0f} ms, over the "
                           f"{1000 * s.budget_s:.0f} ms budget: the scene is too heavy to "
                           "follow live, so coverage is updated on demand")

"""Whether a run's files fit on their disks, judged on what it writes.

Before a scan nobody knows how many of a device's rays return (the sky returns none), so
the budget is measured: the first scan each sensor writes gives its bytes per scan, and
those times the sensor's scans still to come, summed over the sensors whose files go to
one file system, must fit in the space free there. A run that will not fit stops after
that first scan with the estimate, not hours later on a full disk (a run of 1,000,000
frames wrote 42 GB before anything said it needed about 2.5 TB).
"""

import os
import shutil

from ..errors import OutputError

MARGIN = 0.98  # leave the file system a little


class DiskBudget:
    def __init__(self, remaining, free=None):
        """``remaining``: {sensor: scans of it this run will write} (existing files a
        --resume keeps left out); ``free``: f(folder) -> free bytes (shutil's)."""
        self.remaining = dict(remaining)
        self.free = free or (lambda folder: shutil.disk_usage(folder).free)
        self.per_device = {}  # st_dev -> bytes still to come, of the sensors measured
        self.measured = set()
        self.waiting = []  # (sensor, files) written behind the scan, not on disk yet

    def written(self, sensor, files):
        """One scan of ``sensor`` wrote ``files`` (or handed them to a background
        write); on the first of a sensor whose files are complete, check what is to
        come."""
        self.remaining[sensor] = max(0, self.remaining.get(sensor, 1) - 1)
        if sensor not in self.measured:
            self.waiting.append((sensor, [str(f) for f in files]))
        still = []
        for who, paths in self.waiting:
            if who in self.measured:
                continue
            if not paths or not all(os.path.isfile(f) for f in paths):
                still.append((who, paths))
                continue
            self._measure(who, paths)
        self.waiting = [w for w in still if w[0] not in self.measured]

    def _measure(self, sensor, files):
        self.measured.add(sensor)
        size = sum(os.path.getsize(f) for f in files)
        folder = os.path.dirname(os.path.abspath(files[0]))
        device = os.stat(folder).st_dev
        to_come = size * self.remaining[sensor]
        self.per_device[device] = self.per_device.get(device, 0) + to_come
        free = self.free(folder)
        if self.per_device[device] > free * MARGIN:
            need = self.per_device[device]
            raise OutputError(
                f"the run's files will not fit: {sensor}'s first scan wrote "
                f"{_size(size)}, so its {self.remaining[sensor]:,} scans still to come need "
                f"about {_size(to_come)} (with the other sensors measured so far on that "
                f"disk: {_size(need)}), but {_size(free)} are free in {folder}; free some "
                f"space, write elsewhere (--out), or scan fewer frames (--frames)")


def _size(n):
    for unit, scale in (("TB", 1e12), ("GB", 1e9), ("MB", 1e6), ("kB", 1e3)):
        if n >= scale:
            return f"{n / scale:,.1f} {unit}"
    return f"{n:,} bytes"

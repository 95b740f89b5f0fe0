"""A frame's sampled sweep kept between scans of a sensor that cannot move
(``KeptSweeps``): what live coverage reuses while only a LiDAR is moved.

Sampling the scene's motion over a sweep (``sweep.sample_sweep``) asks the scene source
for the state of every object that may move at a few times across the sweep (in
Blender a sub-frame evaluation of the scene each), and ``sweep.classify`` checks the
samples and makes every moving object's track; with the sample intersection's 28 road
users both took 25-35 ms of a 130-165 ms exact-motion rescan at a new place on the
shared machine (docs/study.md). When a still LiDAR is only moved, turned or
retargeted, none of that changes: it depends on the frame, the time within the sweep
and the scene, not on the sensor. ``KeptSweeps`` keeps the states, per (scene, frame,
sweep period) and time, and the classification, and gives them back; ``ScanSession``
uses it only for a sensor that cannot move (a moving sensor's own track is sampled
with the rest, as its sample times depend on it).

Exactness is the caller's contract: the scene must not have changed since the states
were kept, other than the sensor being scanned (and other objects that no state is
read from: sensors, previews). The caller calls ``clear()`` when anything else may
have changed: another object edited, moved or re-animated, the scene's frame rate, an
undo, another file. Given that, a scan with kept states is the scan without them, byte
for byte (each state is the same numbers the source gave; the sampling is the same
code). The frame and the sweep period are part of the key, so another frame or a
preset with another sweep time samples anew (a preset's firing times do not enter the
samples: they only pick which sampled interval each ray falls in, per scan).

What is kept: the matrices and (for objects that may deform) the local vertices at each
sampled time, as the source gave them (read-only), and what ``sweep.classify`` made of
them (``_KeptSweep.motion``: the sample times, which objects move and how, their
tracks), given back while the objects that may move are the same ones, in the same
order, with the same local bounds and matrices at the frame (else classified again,
from the kept states). A deforming object's sub-step meshes (``Sweep.instance_at``) are
read from the source anew at each scan.
"""

import dataclasses
from collections import OrderedDict

KEEP_SWEEPS = 4  # (frame, period) sweeps kept: a few frames or sweep times


class _Kept:
    """The states read at one time of one sweep: which keys (and deformable keys) were
    asked for, and what the source gave (an absent key: not in the scene then)."""

    def __init__(self):
        self.keys, self.deform_keys, self.mats, self.verts = set(), set(), {}, {}

    def covers(self, keys, deform_keys):
        return self.keys.issuperset(keys) and self.deform_keys.issuperset(deform_keys)

    def add(self, keys, deform_keys, mats, verts):
        self.keys |= set(keys)
        self.deform_keys |= set(deform_keys)
        for store, got in ((self.mats, mats), (self.verts, verts)):
            for key, value in got.items():
                if value is not None:
                    value = value.copy()
                    value.setflags(write=False)
                store[key] = value

    def state(self, keys, deform_keys):
        return ({k: self.mats[k] for k in keys if k in self.mats},
                {k: self.verts[k] for k in deform_keys if k in self.verts}, None)


class _Sweep:
    """What is kept of one sweep: the states by time, and the last classification."""

    def __init__(self):
        self.states = {}     # t -> _Kept
        self.motion = None   # (signature of the candidates, their keys, SweepMotion)


class KeptSweeps:
    """Sampled states of the last ``keep`` sweeps (see the module docstring)."""

    def __init__(self, keep=KEEP_SWEEPS):
        self.keep = keep
        self._sweeps = OrderedDict()  # (scene, frame, period) -> _Sweep
        self.hits = 0      # states given back
        self.misses = 0    # states read from the source (and kept)
        self.reused = 0    # classifications given back (no state asked for)
        self.clears = 0

    def clear(self):
        """Forget every kept state (the scene may have changed)."""
        if self._sweeps:
            self.clears += 1
        self._sweeps.clear()

    def __len__(self):
        return sum(len(sweep.states) for sweep in self._sweeps.values())

    def sweep(self, source, frame, period):
        """A ``Sweep`` over ``frame`` of ``source`` that gives kept states back and
        reads (and keeps) the others; the source's own sweep is entered only then."""
        key = (getattr(source, "name", None), int(frame), float(period))
        kept = self._sweeps.pop(key, None)
        if kept is None:
            kept = _Sweep()
            while len(self._sweeps) >= self.keep:
                self._sweeps.popitem(last=False)
        self._sweeps[key] = kept  # (the most recent last)
        return _KeptSweep(self, kept, lambda: source.sweep(frame, period))


class _KeptSweep:
    """``core.scene.source.Sweep`` for a sensor that cannot move: the sensor's matrix
    is never read (``state`` gives None for it)."""

    def __init__(self, store, kept, open_source):
        self.store, self.kept, self.open_source = store, kept, open_source
        self.times = kept.states
        self._cm = self._inner = None

    def _source_sweep(self):
        if self._inner is None:
            self._cm = self.open_source()
            self._inner = self._cm.__enter__()
        return self._inner

    def state(self, t, keys, deform_keys, sensor):
        kept = self.times.get(float(t))
        if kept is not None and kept.covers(keys, deform_keys):
            self.store.hits += 1
            return kept.state(keys, deform_keys)
        self.store.misses += 1
        mats, verts, _ = self._source_sweep().state(t, keys, deform_keys, sensor)
        if kept is None:
            kept = self.times[float(t)] = _Kept()
        kept.add(keys, deform_keys, mats, verts)
        return kept.state(keys, deform_keys)

    def motion(self, instances, mobility, classify):
        """``classify()`` (``sweep.classify`` over this sweep), or the ``SweepMotion``
        it gave for the same candidates (keys in order, local bounds and matrices at
        the frame, deformable keys), its instance indices made this read's."""
        cand = list(mobility.candidates)
        keys = [instances[k].key for k in cand]
        signature = (tuple(keys), tuple(sorted(mobility.deformable)),
                     b"".join(instances[k].vertices.min(0).tobytes()
                              + instances[k].vertices.max(0).tobytes()
                              + instances[k].matrix.tobytes() for k in cand))
        if self.kept.motion is not None and self.kept.motion[0] == signature:
            self.store.reused += 1
            old_keys, motion = self.kept.motion[1:]
            return _reindexed(motion, {old: new for old, new in zip(old_keys, cand)})
        motion = classify()
        self.kept.motion = (signature, cand, motion)
        return motion

    def instance_at(self, t, instance):
        return self._source_sweep().instance_at(t, instance)

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        if self._cm is not None:
            cm, self._cm, self._inner = self._cm, None, None
            return cm.__exit__(*exc)
        return False


def _reindexed(motion, index):
    """``motion`` (a ``SweepMotion`` of a still sensor) with its instance indices mapped
    by ``index`` (old -> new)."""
    return dataclasses.replace(
        motion, rigid=[(index[k], tr) for k, tr in motion.rigid],
        deforming=[(index[k], d) for k, d in motion.deforming],
        tracks={index[k]: tr for k, tr in motion.tracks.items()})

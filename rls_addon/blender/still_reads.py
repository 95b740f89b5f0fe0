"""What a scene read made of the objects that cannot change, kept between the reads of
a file nobody edits (``StillReads``).

A drive through traffic reads the scene every frame: the traffic moves, so the read
cannot be kept whole (``source.BlenderScene``: only a file where nothing changes over
time keeps it). But most of a street stands still (buildings, poles, parked cars), and
reading an object costs 50-150 us a frame (its matrix, bounds, materials, label and
record): 100 parked cars cost 10-25 ms of a 60-110 ms frame. An object that cannot
change (``motion.object_is_still``) reads the same at every frame, so what one read made
of it is given back at the next read with the same centre, range and left-out objects:
the instance record itself, with its materials, or that it was hidden, left out or
beyond the range. The objects that may change are read as always, and the read is the one a
full read gives, object for object and in the same order (tested).

Exactness is ``motion.object_is_still``'s: a mesh object with no modifier or shape key,
not parented, neither it nor its mesh animated or driven, no constraint or rigid body,
no instancing, in a file where no data-block but objects is animated or driven (so
none of its materials, node groups or textures changes) and nothing steps from frame
to frame (``motion.history_free``). Anything else is read every frame.
"""

from collections import OrderedDict
from dataclasses import dataclass, field

KEEP_READS = 4  # reads (centre, range, left out) kept: a driving lidar's cells, a few lidars


@dataclass
class StillEntry:
    """What a read made of one still object: ``kind`` "left" (a helper, or left out),
    "hidden" (from render), "far" (beyond the range), "empty" (no triangle) or "read"
    (then its ``instance``, its ``slot_materials``' names (``read_rules.Named``) and their
    ``infos`` ({name: MaterialInfo}), and its triangles' material slots ``slots``)."""

    full_name: str
    kind: str = "left"
    instance: object = None
    slot_materials: list = field(default_factory=list)
    infos: dict = field(default_factory=dict)
    slots: object = None


class StillReads:
    """``StillEntry``s per read key, for the objects named in ``names``."""

    def __init__(self, names):
        self.names = frozenset(names)
        self._by_key = OrderedDict()

    def at(self, key):
        """The entries ({object name: StillEntry}) of the reads with ``key``, filled by
        the first of them."""
        got = self._by_key.pop(key, None)
        if got is None:
            got = {}
            while len(self._by_key) >= KEEP_READS:
                self._by_key.popitem(last=False)
        self._by_key[key] = got
        return got

"""Every enumeration a user chooses from, defined once: the core validates with it,
Blender's ``EnumProperty`` items and argparse's ``choices`` are made from it.

    MOTION.ids                 ('exact', 'substeps', 'snapshot')
    MOTION.items()             [(id, label, description), ...] for an EnumProperty
    MOTION.check("fast")       SettingsError: unknown motion mode 'fast'; choose one of ...

The extension points are ``Registry`` objects, choices that can grow: the device
families (``device.families.FAMILIES``) and the output formats
(``output.io.formats.FORMATS``), each entry holding what the core and the UI need of it.
"""

import re
from dataclasses import dataclass

from .errors import SettingsError


@dataclass(frozen=True)
class Choice:
    id: str
    label: str
    description: str


class Choices:
    """An ordered set of named choices (``what`` names the setting in messages)."""

    def __init__(self, what, choices):
        self.what = what
        self.choices = tuple(Choice(*c) for c in choices)

    @property
    def ids(self):
        return tuple(c.id for c in self.choices)

    def __iter__(self):
        return iter(self.choices)

    def __len__(self):
        return len(self.choices)

    def __contains__(self, value):
        return value in self.ids

    def items(self):
        """(id, label, description) tuples, as ``bpy.props.EnumProperty(items=...)`` takes."""
        return [(c.id, c.label, c.description) for c in self.choices]

    def label(self, value):
        return next(c.label for c in self.choices if c.id == value)

    def check(self, value):
        """``value`` when it is one of the choices, else ``SettingsError`` naming them."""
        if value not in self.ids:
            raise SettingsError(f"unknown {self.what} {value!r}; choose one of "
                                + ", ".join(self.ids))
        return value


REGISTRY_ID = re.compile(r"^[a-z][a-z0-9_]{0,31}$")


class Registry(Choices):
    """Choices that can grow: one entry per extension (any object with ``id``,
    ``label`` and ``description``), in the order added. ``add`` one, ``remove`` it
    again; whoever shows the list (the UI's menus) ``subscribe``s to hear of changes.
    An id is lower-case letters, digits and '_' (it names Blender enum items and
    menus), at most 32."""

    def __init__(self, what, entries=()):
        super().__init__(what, ())
        self._watchers = []
        for entry in entries:
            self.add(entry)

    def add(self, entry):
        """Add ``entry`` (after the others); returns it. A taken or malformed id is a
        ``SettingsError``."""
        eid = getattr(entry, "id", None)
        if not isinstance(eid, str) or not REGISTRY_ID.match(eid):
            raise SettingsError(f"a {self.what} id must be lower-case letters, digits and '_' "
                                f"(at most 32, starting with a letter), got {eid!r}")
        if eid in self.ids:
            raise SettingsError(f"{self.what} {eid!r} is already registered")
        self.choices += (entry,)
        self._changed()
        return entry

    def remove(self, eid):
        """Take the entry ``eid`` out again (``SettingsError`` when there is none)."""
        self.check(eid)
        self.choices = tuple(c for c in self.choices if c.id != eid)
        self._changed()

    def get(self, eid):
        """The entry ``eid``, else ``SettingsError`` naming the ids there are."""
        self.check(eid)
        return next(c for c in self.choices if c.id == eid)

    def subscribe(self, watcher):
        """Call ``watcher(registry)`` after every change (once per watcher)."""
        if watcher not in self._watchers:
            self._watchers.append(watcher)

    def unsubscribe(self, watcher):
        if watcher in self._watchers:
            self._watchers.remove(watcher)

    def _changed(self):
        for watcher in tuple(self._watchers):
            watcher(self)


MOTION = Choices("motion mode", [
    ("exact", "Exact", "Every ray sees the scene at its own firing time (moving objects and "
                       "a moving sensor distort the cloud as on a real device)"),
    ("substeps", "Sub-steps", "The sweep is split into N partial sweeps, each with one scene "
                              "state (the paper's method; N = 0 chooses N from how far "
                              "things move)"),
    ("snapshot", "Snapshot", "One scene state per frame, as CARLA: no motion distortion"),
])

DETECTION = Choices("detection model", [
    ("auto", "Datasheet", "The LiDAR equation calibrated from the preset's datasheet range "
                          "figures where it has them (what is detected depends on "
                          "reflectivity, incidence, range and weather), else CARLA's model"),
    ("carla", "CARLA", "CARLA's model for every preset: every hit within the range limits "
                       "returns (then noise and the preset's dropout)"),
])

FOOTPRINT = Choices("beam footprint", [
    ("auto", "Preset's Beam", "A beam is a cone of the preset's divergence: rays next to a "
                              "depth edge cast sub-rays, and their echoes become multiple "
                              "returns or mixed points (presets without a divergence: one "
                              "thin ray)"),
    ("off", "Off", "Every ray is one thin line with one return (as before footprints)"),
])

BACKGROUNDS = Choices("detector background", [
    ("empty", "Empty Scene", "Each still LiDAR's sweeps of the scene with every road user "
                             "hidden, the device's noise in each: the background a deployed "
                             "roadside unit has after hours of watching (the default)"),
    ("frames", "From the Frames", "Learned from the frames themselves, traffic and all, as a "
                                  "deployed unit does over a long clip: vehicles standing "
                                  "through most of them become background"),
])

RETURN_MODES = Choices("return mode", [
    ("preset", "Preset", "The device's own return mode (its preset's; strongest unless "
                         "it says otherwise)"),
    ("strongest", "Strongest", "The strongest detected echo of each pulse"),
    ("last", "Last", "The farthest detected echo of each pulse"),
    ("dual", "Dual", "The strongest and the last echo (one point when they are the same)"),
])

WEATHER = Choices("weather", [
    ("clear", "Clear", "Clear air: no extinction, no false returns"),
    ("fog", "Fog", "Fog of a visibility in metres (Koschmieder extinction 3.912 / V)"),
    ("rain", "Rain", "Rain of a rate in mm/h"),
    ("snow", "Snow", "Snowfall of a rate in mm/h water equivalent"),
])

SNOW_TYPES = Choices("snow type", [
    ("dry", "Dry", "Dry snow (attenuates more for the same rate)"),
    ("wet", "Wet", "Wet snow"),
])

BACKENDS = Choices("ray-casting backend", [
    ("auto", "Automatic", "Embree (bundled: embreex with the compiled loop on all cores, or "
                          "pyemblite on macOS) when available, else Blender's BVHTree"),
    ("bvhtree", "BVHTree", "Blender's BVHTree: always available, one core"),
    ("embree", "Embree", "Intel Embree from the bundled embreex or pyemblite wheel (falls back "
                         "to BVHTree with a notice where neither is)"),
])

FRAME_SPACES = Choices("coordinate frame", [
    ("sensor", "Sensor", "Point coordinates in the sensor frame (as the device reports them)"),
    ("world", "World", "Point coordinates in world space"),
])

# Optional point fields of a cloud file (x, y, z are always written).
FIELDS = Choices("point field", [
    ("intensity", "Intensity", "Return strength, 0..1 (float32)"),
    ("ring", "Ring", "Vendor channel index (uint16)"),
    ("time", "Time", "Seconds since the start of the sweep (float64)"),
    ("label", "Label", "Semantic class id (uint32)"),
    ("instance", "Instance", "Per-object id (uint32)"),
    ("ghost", "Ghost", "1 for ghost points from glossy surfaces (uint8)"),
    ("range", "Range", "Distance along the ray in metres (float32)"),
    ("return_index", "Return Index", "Rank by range of the echo among its pulse's echoes, "
                                     "1 = nearest (uint8)"),
    ("num_returns", "Number of Returns", "Echoes the pulse brought back (uint8)"),
])

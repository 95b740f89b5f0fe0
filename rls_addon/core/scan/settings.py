"""What a user chooses for a LiDAR, as plain values: one ``LidarSettings`` per LiDAR.

The Blender layer reads a LiDAR's properties into one of these, once
(``blender.sensor.lidar_settings_of``); the command line overrides it field by field
(``LidarSettings.override``); the core scans and writes with it. Every enumerated
value is checked against ``choices`` here, so a typo anywhere ends in one
``SettingsError`` that lists the valid values.
"""

import dataclasses
import math
import numbers
from dataclasses import dataclass, field

from ..choices import (
    BACKENDS,
    DETECTION,
    FIELDS,
    FOOTPRINT,
    FRAME_SPACES,
    MOTION,
    RETURN_MODES,
)
from ..errors import SettingsError
from ..output.io.fields import DEFAULT_FIELDS, resolve_fields
from ..output.io.formats import FORMATS
from ..output.io.point_types import POINT_TYPE_CHOICES
from ..labels import OBJECT_CLASSES, label_id, label_name
from ..physics.weather import weather_spec

DEFAULT_TEMPLATE = "{scene}_{sensor}_{frame:06d}"
DEFAULT_OUTPUT_DIR = "//lidar/"


@dataclass(frozen=True)
class ScanSettings:
    """How a scan behaves, beyond the device preset.

    Range and noise fields left as None take the preset's values."""

    seed: int = 0  # any whole number >= 0, used whole (effects.scan_rng)
    frame_space: str = "sensor"  # see choices.FRAME_SPACES
    noise: bool = True
    dropout: bool = True
    min_range_m: float | None = None
    max_range_m: float | None = None
    noise_sigma_m: float | None = None
    attenuation_per_m: float | None = None
    # Motion distortion (choices.MOTION): "exact" (every ray at its own time),
    # "substeps" (the paper's N partial sweeps) or "snapshot" (one scene state per
    # frame, as CARLA).
    motion: str = "exact"
    # Sub-steps of "substeps" motion and of deforming objects: 0 chooses N so that
    # nothing moves more than the motion tolerance within one sub-step; N: fixed.
    substeps: int = 0
    motion_tolerance_m: float | None = None  # adaptive sub-step tolerance (None: preset)
    ghosting: bool = True  # ghost points from glossy surfaces
    # Spinning devices: the azimuth (degrees, counter-clockwise from the sensor's +X)
    # where each sweep starts and the last one ended; None: the head's forward (0).
    # An object on this seam is scanned at the start and at the end of the sweep.
    sweep_start_deg: float | None = None
    # Weather as a spec ('fog:visibility=50', 'rain:rate=10', 'snow:rate=2'; see
    # ``weather``), kept in its canonical form; None: clear air
    weather: str | None = None
    # choices.DETECTION: "auto" (the LiDAR equation for presets with datasheet figures)
    # or "carla" (CARLA's model for every preset, as before the LiDAR equation)
    detection: str = "auto"
    # choices.FOOTPRINT: "auto" (a beam is a cone of the preset's divergence, sampled
    # near depth edges; presets without one: a thin ray) or "off" (a thin ray always)
    footprint: str = "auto"
    # choices.RETURN_MODES: "preset" (the device's), "strongest", "last" or "dual"
    return_mode: str = "preset"
    # Spinning devices: the rotation rate (Hz) a unit runs at, a nominal mode or a
    # measured rate (e.g. 10.017), checked against the preset's [modes]; None: the preset's
    rotation_hz: float | None = None
    # Spinning devices with lidar modes (Ouster '1024x10'); None: the preset's default
    lidar_mode: str | None = None

    def __post_init__(self):
        object.__setattr__(self, "seed", _seed(self.seed))
        FRAME_SPACES.check(self.frame_space)
        MOTION.check(self.motion)
        DETECTION.check(self.detection)
        FOOTPRINT.check(self.footprint)
        RETURN_MODES.check(self.return_mode)
        object.__setattr__(self, "weather", weather_spec(self.weather))
        for name, (what, lowest) in _NUMBERS.items():
            _number(getattr(self, name), what, lowest)
        if not math.isfinite(self.substeps) or int(self.substeps) != self.substeps \
                or self.substeps < 0:
            raise SettingsError(f"sub-steps must be a whole number >= 0 (0: adaptive), "
                                f"got {self.substeps}")


# The number fields of ScanSettings (None: the preset's): what a user calls them, and
# the least value that means something (">= 0", "> 0" or None: any finite number).
_NUMBERS = {"min_range_m": ("the minimum range (min_range_m, m)", ">= 0"),
            "max_range_m": ("the maximum range (max_range_m, m)", "> 0"),
            "noise_sigma_m": ("the noise sigma (noise_sigma_m, m)", ">= 0"),
            "attenuation_per_m": ("the attenuation (attenuation_per_m, 1/m)", ">= 0"),
            "motion_tolerance_m": ("the motion tolerance (motion_tolerance_m, m)", ">= 0"),
            "sweep_start_deg": ("the sweep start (sweep_start_deg, degrees)", None),
            "rotation_hz": ("the rotation rate (rotation_hz, Hz)", "> 0")}


def _number(value, what, lowest):
    """``SettingsError`` naming the setting ``what`` unless ``value`` is None or a
    finite number satisfying ``lowest``."""
    if value is None:
        return
    if isinstance(value, bool) or not isinstance(value, numbers.Real):
        raise SettingsError(f"{what} must be a number, got {value!r}")
    if not math.isfinite(value):
        raise SettingsError(f"{what} must be a finite number, got {value!r}")
    if (lowest == ">= 0" and value < 0) or (lowest == "> 0" and value <= 0):
        raise SettingsError(f"{what} must be {lowest}, got {value!r}")


def _seed(seed):
    """A scan seed as a Python int: any whole number >= 0 (``effects.scan_rng`` uses all
    of it); a negative one is refused rather than folded onto another seed."""
    if isinstance(seed, bool) or not isinstance(seed, numbers.Integral) or seed < 0:
        raise SettingsError(f"the seed must be a whole number >= 0, got {seed!r}")
    return int(seed)


@dataclass(frozen=True)
class OutputSettings:
    """Where and how a LiDAR's clouds are written (its Output panel)."""

    directory: str = DEFAULT_OUTPUT_DIR  # '//' is the folder of the .blend file
    format: str = "pcd_binary"           # see output.io.formats.FORMATS
    fields: tuple = DEFAULT_FIELDS  # x, y, z and every field but 'range'
    template: str = DEFAULT_TEMPLATE
    # Ground truth in the sidecar: boxes of the objects of these classes (label names)
    ground_truth: bool = True
    object_classes: tuple = OBJECT_CLASSES
    # Absolute time (s, e.g. a Unix time) of the scene's first frame: frame f starts
    # at start_time_s + (f - first frame) / frame rate
    start_time_s: float = 0.0
    # PCD, PLY and bags: the fields of a vendor ROS driver's point (io.point_types) or
    # RLS's own ("rls": ``fields`` choose among them)
    point_type: str = "rls"
    # LAS: world offset (m, x y z; None: per file, its minimum floored to whole km) and
    # the world frame's CRS ('EPSG:<code>' or None)
    las_offset: tuple | None = None
    crs: str | None = None

    def __post_init__(self):
        FORMATS.check(self.format)
        POINT_TYPE_CHOICES.check(self.point_type)
        _number(self.start_time_s, "the start time (start_time_s, s)", None)
        if self.las_offset is not None:
            if len(tuple(self.las_offset)) != 3:
                raise SettingsError(f"a LAS offset is x, y, z in metres, got {self.las_offset!r}")
            for axis, v in zip("xyz", self.las_offset):  # a NaN offset makes every X -2^31
                _number(v, f"the LAS offset's {axis} (las_offset, m)", None)
        for f in self.fields:
            if f not in ("x", "y", "z"):
                FIELDS.check(f)
        # x, y, z first and always; the rest in the files' own order
        object.__setattr__(self, "fields", resolve_fields(tuple(self.fields)))
        object.__setattr__(self, "object_classes", tuple(label_name(label_id(c))
                                                         for c in self.object_classes))


@dataclass(frozen=True)
class LidarSettings:
    """Everything about one LiDAR but its pose: the device, the scan, the output."""

    preset: str = "generic_uniform32"    # device preset id
    scan: ScanSettings = field(default_factory=ScanSettings)
    output: OutputSettings = field(default_factory=OutputSettings)
    backend: str = "auto"                # see choices.BACKENDS

    def __post_init__(self):
        BACKENDS.check(self.backend)

    def override(self, **changes):
        """A copy with the given fields replaced; a change of None keeps the value (so
        unset command-line flags pass straight through). Names are those of this
        class, ``ScanSettings`` or ``OutputSettings``; an unknown name is an error."""
        changes = {k: v for k, v in changes.items() if v is not None}
        scan_names = {f.name for f in dataclasses.fields(ScanSettings)}
        out_names = {f.name for f in dataclasses.fields(OutputSettings)}
        own = {"preset", "backend"}
        unknown = sorted(set(changes) - scan_names - out_names - own)
        if unknown:
            raise SettingsError(f"unknown setting(s) {', '.join(unknown)}")
        scan = dataclasses.replace(self.scan, **{k: v for k, v in changes.items()
                                                 if k in scan_names})
        output = dataclasses.replace(self.output, **{k: v for k, v in changes.items()
                                                     if k in out_names})
        return dataclasses.replace(self, scan=scan, output=output,
                                   **{k: v for k, v in changes.items() if k in own})


def preset_in_modes(preset, settings):
    """``preset`` as the unit runs with ``settings`` (a ``ScanSettings``): its rotation
    rate and lidar mode (``modes.with_modes``; the same preset when both are None)."""
    from ..device.modes import with_modes

    return with_modes(preset, settings.rotation_hz, settings.lidar_mode, settings.return_mode)


def scan_pattern(preset, settings, frame):
    """The ``ScanPattern`` a scan casts: the preset's for ``frame``, its sweep started
    where ``settings.sweep_start_deg`` says (spinning devices only)."""
    pattern = preset.pattern(frame)
    if settings.sweep_start_deg is None:
        return pattern
    if preset.family != "spinning":
        raise SettingsError(f"'{preset.id}' is a {preset.family} device: a sweep start is "
                            "only defined for spinning devices")
    return pattern.started_at(settings.sweep_start_deg)


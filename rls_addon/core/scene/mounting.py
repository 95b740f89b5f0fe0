"""Where a LiDAR goes (``LidarMounting``): its device, its name, on a mount object or at
a point, pitched and yawed or facing the region. ``rls lidar add``, the sample scenes'
LiDAR and ``rls demo`` fill one and the Blender layer makes the object; a study's
candidates face the region the same way (``facing_yaw_deg``).

Angles are degrees; a positive pitch tilts the sensor's +X below the horizon, a yaw
turns +X counter-clockwise from world +X (seen from above). The object's Euler angles
(Blender's XYZ order) are then (roll, pitch, yaw), as ``study.candidates.pose_matrix``
builds the same pose.
"""

import dataclasses
import math
import struct

from ..errors import SceneError

# Blender's longest object name (bytes of UTF-8), measured on bpy 5.0.1: a longer name
# is cut short without a word, and the LiDAR would not be called what was asked.
MAX_NAME_BYTES = 255
DEFAULT_NAME = "LiDAR"


def facing_yaw_deg(position, target_xy):
    """Yaw (degrees) that points +X from ``position`` towards ``target_xy``."""
    dx, dy = target_xy[0] - position[0], target_xy[1] - position[1]
    if abs(dx) < 1e-12 and abs(dy) < 1e-12:
        return 0.0
    return math.degrees(math.atan2(dy, dx))


def parse_position(text, option="--at"):
    """(x, y, z) metres of 'X,Y,Z', every one a finite number, or a ``SceneError``."""
    parts = str(text).split(",")
    try:
        values = tuple(float(p) for p in parts)
    except ValueError:
        values = ()
    if len(values) != 3:
        raise SceneError(f"{option}: expected X,Y,Z in metres, got {text!r}")
    if not all(math.isfinite(v) for v in values):
        raise SceneError(f"{option}: every coordinate must be a finite number, got {text!r}")
    for v in values:
        kept = _as_float32(v)
        if kept is None or abs(kept - v) > FLOAT32_TOLERANCE_M:
            held = "cannot hold it" if kept is None else \
                f"would hold it as {kept!r}, {abs(kept - v):.3g} m away (more than " \
                f"{FLOAT32_TOLERANCE_M * 1e3:g} mm)"
            raise SceneError(
                f"{option}: {v!r} m: Blender keeps an object's location in 32-bit floats, "
                f"which {held}; place the scene and its LiDARs nearer the world origin "
                f"(got {text!r})")
    return values


# how far a position may move when Blender stores it in 32-bit floats (its spacing
# passes 1 mm at about 8 km from the origin; a value it holds exactly is always kept)
FLOAT32_TOLERANCE_M = 1e-3


def _as_float32(v):
    """``v`` rounded to a 32-bit float, as Blender stores it; None beyond its range."""
    try:
        return struct.unpack("<f", struct.pack("<f", v))[0]
    except OverflowError:
        return None


def check_name(name):
    """``name`` if Blender can keep it as a LiDAR's object name, else a ``SceneError``."""
    if not isinstance(name, str) or not name.strip():
        raise SceneError("a LiDAR needs a name (--name)")
    if name != name.strip():
        raise SceneError(f"the name {name!r} starts or ends with spaces: other commands "
                         "would not find it by what is typed")
    if len(name.encode("utf-8")) > MAX_NAME_BYTES:
        raise SceneError(f"the name is {len(name.encode('utf-8'))} bytes long; Blender keeps "
                         f"at most {MAX_NAME_BYTES}")
    return name


def _finite(value, option):
    if value is None:
        return None
    v = float(value)
    if not math.isfinite(v):
        raise SceneError(f"{option} must be a finite number of degrees, got {value!r}")
    return v


@dataclasses.dataclass(frozen=True)
class LidarMounting:
    """A LiDAR to add: ``mount`` (an object's name: the LiDAR sits on its top) or ``at``
    (x, y, z in metres), exactly one; ``pitch_deg`` nose down; ``yaw_deg`` or
    ``face_region`` (towards the middle of the region's outline), at most one (neither:
    yaw 0, along world +X)."""

    preset: str
    name: str = DEFAULT_NAME
    mount: str = None
    at: tuple = None
    pitch_deg: float = 0.0
    yaw_deg: float = None
    face_region: bool = False

    def __post_init__(self):
        check_name(self.name)
        if not self.preset or not str(self.preset).strip():
            raise SceneError("a LiDAR needs a device preset (--preset ID; rls presets list)")
        if (self.mount is None) == (self.at is None):
            raise SceneError("say where the LiDAR goes: --mount OBJECT or --at X,Y,Z (one of them)")
        if self.at is not None:
            at = tuple(float(v) for v in self.at)
            if len(at) != 3 or not all(math.isfinite(v) for v in at):
                raise SceneError(f"--at: expected three finite coordinates, got {self.at!r}")
            object.__setattr__(self, "at", at)
        pitch = _finite(self.pitch_deg, "--pitch")
        if not -90.0 <= pitch <= 90.0:
            raise SceneError(f"--pitch must be between -90 and 90 degrees, got {pitch:g}")
        object.__setattr__(self, "pitch_deg", pitch)
        object.__setattr__(self, "yaw_deg", _finite(self.yaw_deg, "--yaw"))
        if self.yaw_deg is not None and self.face_region:
            raise SceneError("give --yaw or --face-region, not both")

    def yaw_at(self, position, region_centre=None):
        """The yaw in degrees at ``position``: the given one, towards ``region_centre``
        (x, y) with ``face_region``, else 0."""
        if self.face_region:
            if region_centre is None:
                raise SceneError("--face-region needs the scene's InfraLOB region")
            return facing_yaw_deg(position, region_centre)
        return 0.0 if self.yaw_deg is None else self.yaw_deg

    def euler(self, position, region_centre=None):
        """The object's XYZ Euler angles in radians: (roll 0, pitch, yaw)."""
        return (0.0, math.radians(self.pitch_deg),
                math.radians(self.yaw_at(position, region_centre)))

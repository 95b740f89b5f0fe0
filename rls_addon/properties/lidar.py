"""The LiDAR's properties: one ``PropertyGroup`` per LiDAR object (``Object.rls_lidar``),
with the device preset list its enums show.

Only plain values live here; ``blender.sensor.read_settings`` maps them into the core's
``LidarSettings`` in one place. Enumerations come from ``core.choices`` and the
registries (the Format list from ``output.io.formats.FORMATS``, the preset list grouped
by ``device.families.FAMILIES``), the same lists the core validates with and the
command line offers.
"""

import bpy
from bpy.props import (
    BoolProperty,
    EnumProperty,
    FloatProperty,
    IntProperty,
    StringProperty,
)

from ..blender import preset_catalog
from ..blender.preview import COLOR_ATTRIBUTES
from ..blender.sensor import DEFAULT_PRESET
from ..core.choices import (
    BACKENDS,
    DETECTION,
    FIELDS,
    FOOTPRINT,
    FRAME_SPACES,
    MOTION,
    RETURN_MODES,
    SNOW_TYPES,
    WEATHER,
)
from ..core.errors import RLSError
from ..core.output.io import DEFAULT_FIELDS
from ..core.output.io.formats import FORMATS
from ..core.output.io.point_types import POINT_TYPE_CHOICES
from ..core.labels import DEFAULT_LABELS, label_id

COLOR_ITEMS = [(a, a.title(), f"Colour preview points by {a}") for a in COLOR_ATTRIBUTES]

_ITEMS = {"presets": [], "old": [], "formats": ((), [])}  # enum items must stay referenced
# while Blender shows them


def preset_items(self, context):
    """Enum items of the device presets, grouped by family (built-in and user)."""
    if not _ITEMS["presets"]:
        items, n = [], 0
        for fam, entries in preset_catalog.by_family():
            if items:
                items.append(None)
            items.append(("", fam.label, ""))
            for e in entries:
                tag = "built-in" if e.builtin else "user preset"
                items.append((e.id, e.name, f"{e.source} ({tag})", "NONE" if e.builtin else "USER", n))
                n += 1
        _ITEMS["presets"] = items
    return _ITEMS["presets"]


def format_items(self, context):
    """Enum items of the output formats, as the registry has them now (``FORMATS``):
    numbered in its order, so the built-in formats keep the numbers a .blend stored
    before the list could grow."""
    entries, items = _ITEMS["formats"]
    if entries is not FORMATS.choices:
        if items:
            _ITEMS["old"].append(items)
            del _ITEMS["old"][:-4]
        items = [(f.id, f.label, f.description, i) for i, f in enumerate(FORMATS)]
        _ITEMS["formats"] = (FORMATS.choices, items)
    return items


_MODE_ITEMS = {}  # preset id -> enum items (kept alive: Blender holds the strings)


def lidar_mode_items(self, context):
    """Enum items of the lidar modes of this LiDAR's preset ([modes] lidar_mode), the
    preset's default first as 'DEFAULT'."""
    pid = self.preset_id or DEFAULT_PRESET
    got = _MODE_ITEMS.get(pid)
    if got is None:
        e = preset_catalog.entry(pid)  # the cached catalog: no file is read here
        default = e.default_lidar_mode if e else None
        got = [("DEFAULT", f"Preset ({default})" if default else "Preset",
                "The preset's default mode", 0)]
        for i, m in enumerate(e.lidar_modes if e else (), start=1):
            cols, _, rate = m.partition("x")
            got.append((m, m, f"{cols} columns at {rate} Hz", i))
        _MODE_ITEMS[pid] = got
    return got


def refresh_preset_items():
    """Rebuild the preset list after user presets changed."""
    preset_catalog.refresh()
    _MODE_ITEMS.clear()
    if _ITEMS["presets"]:
        _ITEMS["old"].append(_ITEMS["presets"])  # keep the strings alive for open menus
        del _ITEMS["old"][:-4]
    _ITEMS["presets"] = []


def _preset_number(preset_id):
    for it in preset_items(None, None):
        if it and it[0] == preset_id:
            return it[4]
    return -1


def _get_preset(self):
    return _preset_number(self.preset_id or DEFAULT_PRESET)


def _set_preset(self, value):
    for it in preset_items(None, None):
        if it and it[0] and it[4] == value:
            self.preset_id = it[0]
            return


def _update_fov(self, context):
    obj = self.id_data
    if not isinstance(obj, bpy.types.Object) or not self.is_lidar:
        return
    from ..blender import fov

    if not self.show_fov:
        fov.remove_fov(obj)
        return
    try:
        preset = preset_catalog.resolve(self.preset_id)
    except Exception:  # noqa: BLE001 - a broken preset shows in the panel, not here
        return
    fov.update_fov(obj, preset, self.fov_length)


def _update_preset(self, context):
    obj = self.id_data
    if isinstance(obj, bpy.types.Object) and self.show_fov:
        _update_fov(self, context)


LABEL_ITEMS = [("NONE", "From Collections", "No rls_label property: the label comes from the "
                "name of one of the object's collections (Road, Buildings, ...)", 0)] + [
    (name.upper(), name.replace("_", " ").title(), f"Label id {i}", i + 1)
    for i, name in DEFAULT_LABELS.items()]


def _get_label(self):
    value = self.id_data.get("rls_label")
    if value is None:
        return 0
    try:
        return label_id(value if not isinstance(value, str) or not value.isdigit() else int(value)) + 1
    except (RLSError, TypeError, ValueError):
        return 0


def _set_label(self, value):
    obj = self.id_data
    if value == 0:
        if "rls_label" in obj:
            del obj["rls_label"]
    else:
        obj["rls_label"] = DEFAULT_LABELS[value - 1]


class RLS_LidarSettings(bpy.types.PropertyGroup):
    is_lidar: BoolProperty(name="Is LiDAR", default=False,
                           description="This object is a LiDAR sensor; its axes are the sensor frame")
    preset_id: StringProperty(name="Device Id", default=DEFAULT_PRESET, update=_update_preset,
                              description="Id of the device preset (built-in or user preset)")
    preset: EnumProperty(name="Device", items=preset_items, get=_get_preset, set=_set_preset,
                         description="Device preset: scan pattern, range and noise of a real sensor")
    show_fov: BoolProperty(name="Show Field of View", default=False, update=_update_fov,
                           description="Outline the device's field of view in the viewport "
                                       "(a wire object parented to the LiDAR, never rendered)")
    fov_length: FloatProperty(name="FOV Size", default=3.0, min=0.1, soft_max=50.0, unit="LENGTH",
                              update=_update_fov, description="Distance at which the field of view is drawn")
    seed: IntProperty(name="Seed", default=0, min=0,
                      description="Seed of the scan's random generator (noise, dropout, ghosts)")
    noise: BoolProperty(name="Range Noise", default=True,
                        description="Add the device's Gaussian range noise")
    use_noise_sigma: BoolProperty(name="Override Noise", default=False,
                                  description="Use your own range noise instead of the preset's")
    noise_sigma: FloatProperty(name="Noise Sigma", default=0.02, min=0.0, soft_max=0.2, unit="LENGTH",
                               precision=4, description="Standard deviation of the range noise")
    dropout: BoolProperty(name="Dropout", default=True,
                          description="Drop returns as the device's dropout model says")
    use_min_range: BoolProperty(name="Override Min Range", default=False,
                                description="Use your own blind zone instead of the preset's")
    min_range: FloatProperty(name="Min Range", default=0.5, min=0.0, soft_max=10.0, unit="LENGTH",
                             description="Blind zone: no returns closer than this")
    use_max_range: BoolProperty(name="Override Range", default=False,
                                description="Use your own maximum range instead of the preset's")
    max_range: FloatProperty(name="Max Range", default=100.0, min=0.1, soft_max=500.0,
                             unit="LENGTH", description="No returns beyond this")
    detection: EnumProperty(name="Detection", items=DETECTION.items(), default="auto",
                            description="What the device detects: the LiDAR equation from "
                                        "its datasheet's range figures, or CARLA's model")
    footprint: EnumProperty(name="Beam Footprint", items=FOOTPRINT.items(), default="auto",
                            description="A beam as a cone of the preset's divergence: rays "
                                        "next to a depth edge bring back several echoes "
                                        "or a mixed point (presets without a divergence: "
                                        "thin rays)")
    return_mode: EnumProperty(name="Return Mode", items=RETURN_MODES.items(),
                              default="preset",
                              description="Which echoes of a pulse the device reports")
    use_rotation_hz: BoolProperty(name="Set Rotation Rate", default=False,
                                  description="Spin at your own rate (a mode of the device or "
                                              "a unit's measured rate) instead of the preset's")
    rotation_hz: FloatProperty(name="Rotation (Hz)", default=10.0, min=0.1, soft_max=30.0,
                               precision=3, description="Rotation rate of a spinning device, "
                                                        "e.g. 10.017 measured on a unit; "
                                                        "checked against the device's modes")
    lidar_mode: EnumProperty(name="Lidar Mode", items=lidar_mode_items,
                             description="Columns x rate of devices with lidar modes (Ouster)")
    weather: EnumProperty(name="Weather", items=WEATHER.items(), default="clear",
                          description="Fog, rain or snow: returns are dimmed by the air's "
                                      "two-way transmission (and lost where the device's "
                                      "LiDAR equation says so), and the air sends false "
                                      "returns near the sensor (label 'weather')")
    fog_visibility: FloatProperty(name="Visibility", default=100.0, min=1.0, soft_max=2000.0,
                                  unit="LENGTH", description="Fog: visibility (Koschmieder)")
    precipitation_rate: FloatProperty(name="Rate (mm/h)", default=5.0, min=0.01, max=500.0,
                                      soft_max=50.0, precision=2,
                                      description="Rain or snowfall rate in mm/h (snow: "
                                                  "water equivalent)")
    snow_type: EnumProperty(name="Snow", items=SNOW_TYPES.items(), default="dry",
                            description="Dry or wet snow")
    motion: EnumProperty(name="Motion", items=MOTION.items(), default="exact",
                         description="How moving objects and a moving sensor are scanned")
    substeps: IntProperty(name="Sub-steps", default=0, min=0, soft_max=64,
                          description="Partial sweeps per frame in Sub-steps motion and for "
                                      "deforming objects (0: chosen from how far things "
                                      "move, so that nothing moves more than the range "
                                      "noise within one)")
    use_sweep_start: BoolProperty(
        name="Set Sweep Start", default=False,
        description="Start each sweep at your own azimuth instead of the head's forward "
                    "direction (spinning devices)")
    sweep_start: FloatProperty(
        name="Sweep Start", default=180.0, min=-360.0, max=360.0, precision=1,
        description="Azimuth in degrees (counter-clockwise from the LiDAR's +X) where each "
                    "sweep starts and the last one ended: an object there is scanned at both "
                    "ends of the sweep, a period apart. 180 (behind the sensor) keeps the "
                    "seam off the road a pole LiDAR watches")
    ghosting: BoolProperty(name="Ghost Points", default=True,
                           description="Ghost points from glossy surfaces (mirror-like bounces)")
    backend: EnumProperty(name="Ray Casting", default="auto", items=BACKENDS.items(),
                          description="The ray-casting backend: same points, different speed")
    frame_space: EnumProperty(name="Frame", default="sensor", items=FRAME_SPACES.items(),
                              description="Coordinate frame of the written points")
    output_dir: StringProperty(name="Output", subtype="DIR_PATH", default="//lidar/",
                               description="Folder the clouds and sidecars are written to "
                                           "('//' is the folder of the .blend file)")
    file_format: EnumProperty(name="Format", items=format_items, default=0,  # pcd_binary
                              description="Point cloud file format")
    fields: EnumProperty(name="Fields", items=FIELDS.items(), options={"ENUM_FLAG"},
                         default={f for f in DEFAULT_FIELDS if f not in ("x", "y", "z")},
                         description="Point fields to write (x, y, z are always written)")
    point_type: EnumProperty(name="Point Type", items=POINT_TYPE_CHOICES.items(), default="rls",
                             description="Fields, names, types and units of the written points: "
                                         "RLS's own (the Fields below) or those a vendor's ROS "
                                         "driver publishes (PCD, PLY and ROS 2 bags)")
    crs: StringProperty(name="CRS", default="",
                        description="LAS: the coordinate reference system of the scene's world "
                                    "frame, as 'EPSG:<code>' (empty: none written)")
    name_template: StringProperty(name="Names", default="{scene}_{sensor}_{frame:06d}",
                                  description="File name template: {scene}, {sensor}, {frame:06d}; "
                                              "slashes make sub-folders")
    ground_truth: BoolProperty(
        name="Ground Truth", default=True,
        description="Write 3D boxes of the objects of the object classes into each sidecar "
                    "(size, heading, velocity, points, visibility)")
    object_classes: StringProperty(
        name="Object Classes", default="vehicle,pedestrian,cyclist",
        description="Labels whose objects get ground-truth boxes (names or ids, comma "
                    "separated)")
    preview_color: EnumProperty(name="Color By", items=COLOR_ITEMS, default="intensity",
                                description="Attribute the preview points are coloured by")
    label: EnumProperty(name="Semantic Label", items=LABEL_ITEMS, get=_get_label, set=_set_label,
                        description="The object's rls_label property: the class its points get")

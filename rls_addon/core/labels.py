"""Semantic labels: a fixed default table of class ids and names.

Objects get a label from a custom property (``rls_label``, a name or id) or from the
name of a collection they are in; matching is case-insensitive on the names and the
aliases below, Blender's duplicate suffix left out (a collection "Road.001", made when
a file already holds a "Road", is road). Ids are stable across versions: new classes
are only ever appended.
"""

import re

from .errors import RLSError

DEFAULT_LABELS = {
    0: "unlabeled",
    1: "road",
    2: "sidewalk",
    3: "building",
    4: "wall",
    5: "fence",
    6: "pole",
    7: "traffic_light",
    8: "traffic_sign",
    9: "vegetation",
    10: "terrain",
    11: "vehicle",
    12: "pedestrian",
    13: "glass",
    14: "water",
    15: "ground",
    16: "static",
    17: "metal",
    18: "cyclist",
    19: "weather",   # false returns from fog, rain or snow near the sensor (instance 0)
}

# The label of false returns from the air (``weather``).
WEATHER_LABEL = 19

# Labels whose objects get ground-truth boxes by default (see ``ground_truth``).
OBJECT_CLASSES = ("vehicle", "pedestrian", "cyclist")

ALIASES = {
    "roads": "road",
    "street": "road",
    "sidewalks": "sidewalk",
    "pavement": "sidewalk",
    "buildings": "building",
    "walls": "wall",
    "fences": "fence",
    "poles": "pole",
    "traffic_lights": "traffic_light",
    "trafficlight": "traffic_light",
    "traffic_signs": "traffic_sign",
    "trafficsign": "traffic_sign",
    "trees": "vegetation",
    "tree": "vegetation",
    "vehicles": "vehicle",
    "car": "vehicle",
    "cars": "vehicle",
    "pedestrians": "pedestrian",
    "people": "pedestrian",
    "person": "pedestrian",
    "cyclists": "cyclist",
    "bicycle": "cyclist",
    "bicycles": "cyclist",
    "bike": "cyclist",
    "bikes": "cyclist",
    "rider": "cyclist",
    "truck": "vehicle",
    "trucks": "vehicle",
    "bus": "vehicle",
    "weather_noise": "weather",
}

NAME_TO_ID = {name: i for i, name in DEFAULT_LABELS.items()}

# Road users: the classes with ground-truth boxes, which a placement study leaves out of
# its traffic-free scans and a deployed unit's background never holds.
ROAD_USERS = ("vehicle", "pedestrian", "cyclist")


# Blender's name for a second datablock of a taken name: "Road.001"
DUPLICATE_SUFFIX = re.compile(r"\.\d{3,}$")


def base_name(name):
    """``name`` without Blender's duplicate suffix ("Road.001" -> "Road")."""
    return DUPLICATE_SUFFIX.sub("", str(name))


def _norm(name):
    return base_name(str(name).strip()).lower().replace(" ", "_").replace("-", "_")


def match_label(name):
    """The label id a name stands for, or None when it names no class."""
    key = _norm(name)
    key = ALIASES.get(key, key)
    return NAME_TO_ID.get(key)


def label_id(value):
    """Resolve a label given as an id or a name; raise RLSError for unknown values."""
    if isinstance(value, bool):
        raise RLSError(f"label must be a name or an id, got {value!r}")
    if isinstance(value, int):
        if value in DEFAULT_LABELS:
            return value
        raise RLSError(f"unknown label id {value}; known ids are 0..{max(DEFAULT_LABELS)}")
    found = match_label(value)
    if found is None:
        raise RLSError(f"unknown label '{value}'; known: {', '.join(DEFAULT_LABELS.values())}")
    return found


def label_name(label):
    """Name of a label id ('label_<id>' for ids outside the table)."""
    return DEFAULT_LABELS.get(int(label), f"label_{int(label)}")


def label_ids(names):
    """Resolve an iterable of names or ids (or a comma-separated string) to a sorted id list."""
    if isinstance(names, str):
        names = [n for n in names.split(",") if n.strip()]
    return sorted({label_id(int(n) if str(n).strip().isdigit() else n) for n in names})

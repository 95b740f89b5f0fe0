"""Vehicle types: the size (length, width, height) of every type a SUMO run used, and
the RLS class and mesh shape it gets.

Sizes come from ``<vType>`` elements of a route or additional file (``--vtypes``);
an attribute a vType leaves out takes SUMO's default for its ``vClass``, as SUMO itself
does; a type id that no file defines is sized only when it is one of SUMO's built-in
types (``DEFAULT_VEHTYPE``, ``DEFAULT_PEDTYPE``, ``DEFAULT_BIKETYPE`` ...). Any other
type id, or a size that is not a positive number, is an ``InputError`` naming it.

The defaults below are SUMO's own, from its source (eclipse-sumo/sumo,
src/utils/vehicle/SUMOVTypeParameter.cpp, ``VClassDefaultValues``: width and height per
vClass, else DEFAULT_VEH_WIDTH 1.8 and DEFAULT_VEH_HEIGHT 1.5 of SUMOVehicleClass.cpp;
length from ``getDefaultVehicleLength`` in src/utils/common/SUMOVehicleClass.cpp, 5 m
for every class it does not list), tabled in the SUMO documentation page "Vehicle Type
Parameter Defaults" (sumo.dlr.de/docs/Vehicle_Type_Parameter_Defaults.html).
"""

import math
import xml.etree.ElementTree as ET
from dataclasses import dataclass

from ..errors import InputError
from ..roads.network import refuse_internal_dtd
from .xml_errors import parse_reason

# vClass -> (length, width, height) in metres (SUMO 1.28 source, see the module doc;
# each checked against SUMO 1.28.0's own types, read back with TraCI's
# vehicletype.getLength/getWidth/getHeight: wheelchair 1.2 x 0.72 x 1.2 and scooter
# 1.2 x 0.5 x 1.7, not getDefaultVehicleLength's 5 m of older SUMO; the class SUMO
# calls "evehicle", which it refuses as "e_vehicle").
VCLASS_DEFAULTS = {
    "passenger": (5.0, 1.8, 1.5), "private": (5.0, 1.8, 1.5), "vip": (5.0, 1.8, 1.5),
    "hov": (5.0, 1.8, 1.5), "taxi": (5.0, 1.8, 1.5), "evehicle": (5.0, 1.8, 1.5),
    "custom1": (5.0, 1.8, 1.5), "custom2": (5.0, 1.8, 1.5),
    "pedestrian": (0.215, 0.478, 1.719),
    "wheelchair": (1.2, 0.72, 1.2),
    "bicycle": (1.6, 0.65, 1.7),
    "scooter": (1.2, 0.5, 1.7),
    "moped": (2.1, 0.78, 1.7),
    "motorcycle": (2.2, 0.9, 1.5),
    "truck": (7.1, 2.4, 2.4),
    "trailer": (16.5, 2.55, 4.0),
    "bus": (12.0, 2.5, 3.4),
    "coach": (14.0, 2.6, 4.0),
    "delivery": (6.5, 2.16, 2.86),
    "emergency": (6.5, 2.16, 2.86),
    "army": (5.0, 1.8, 1.5), "authority": (5.0, 1.8, 1.5), "ignoring": (5.0, 1.8, 1.5),
}

# SUMO's built-in type ids and their vClass (SUMOVehicleClass.cpp, DEFAULT_*TYPE_ID).
BUILTIN_TYPES = {
    "DEFAULT_VEHTYPE": "passenger",
    "DEFAULT_PEDTYPE": "pedestrian",
    "DEFAULT_BIKETYPE": "bicycle",
    "DEFAULT_TAXITYPE": "taxi",
    "DEFAULT_CONTAINERTYPE": "ignoring",
}

# vClass -> (RLS label name, mesh shape)
CLASS_OF = {
    "pedestrian": ("pedestrian", "pedestrian"), "wheelchair": ("pedestrian", "pedestrian"),
    "bicycle": ("cyclist", "bicycle"), "scooter": ("cyclist", "bicycle"),
    "moped": ("cyclist", "motorcycle"), "motorcycle": ("vehicle", "motorcycle"),
    "truck": ("vehicle", "truck"), "trailer": ("vehicle", "truck"),
    "bus": ("vehicle", "bus"), "coach": ("vehicle", "bus"),
    "delivery": ("vehicle", "van"), "emergency": ("vehicle", "van"),
}
SHAPES = ("car", "van", "truck", "bus", "motorcycle", "bicycle", "pedestrian")


@dataclass(frozen=True)
class VType:
    id: str
    vclass: str
    length: float
    width: float
    height: float

    @property
    def size(self):
        return (self.length, self.width, self.height)

    @property
    def label(self):
        return CLASS_OF.get(self.vclass, ("vehicle", "car"))[0]

    @property
    def shape(self):
        return CLASS_OF.get(self.vclass, ("vehicle", "car"))[1]


def _size(value, name, what, path):
    try:
        v = float(value)
    except (TypeError, ValueError):
        v = math.nan
    if not math.isfinite(v) or v <= 0:
        raise InputError(f"{path}: vType {name!r} has {what} {value!r}: a vType needs a "
                         f"positive length, width and height (m)")
    return v


def make_vtype(type_id, attrs, path="vType"):
    """A ``VType`` from a vType element's attributes (SUMO's vClass defaults for those
    it leaves out)."""
    vclass = attrs.get("vClass", "passenger")
    if vclass not in VCLASS_DEFAULTS:
        raise InputError(f"{path}: vType {type_id!r} has vClass {vclass!r}, which RLS "
                         f"does not know (one of {', '.join(sorted(VCLASS_DEFAULTS))})")
    d = VCLASS_DEFAULTS[vclass]
    return VType(type_id, vclass,
                 *(_size(attrs.get(k, dv), type_id, k, path)
                   for k, dv in zip(("length", "width", "height"), d)))


def read_vtypes(path):
    """{id: VType} of every ``<vType>`` in a SUMO route or additional file (streamed;
    any other element is skipped)."""
    out = {}
    refuse_internal_dtd(path)
    try:
        for _, el in ET.iterparse(path, events=("end",)):
            if el.tag == "vType":
                tid = el.get("id")
                if not tid:
                    raise InputError(f"{path}: a <vType> without an id")
                out[tid] = make_vtype(tid, el.attrib, path)
                el.clear()
            elif el.tag in ("vehicle", "trip", "flow", "person", "route"):
                el.clear()
    except ET.ParseError as exc:
        raise InputError(f"{path} is not a readable SUMO XML file: {parse_reason(exc)}") \
            from None
    except OSError as exc:
        raise InputError(f"cannot read vType file {path}: {exc.strerror or exc}") from None
    return out


def resolve(type_ids, vtypes, source="the FCD"):
    """{type id: VType} for every id in ``type_ids``: from ``vtypes`` (read files), else
    SUMO's built-in types; an unknown id is an ``InputError``."""
    out = {}
    for tid in sorted(type_ids):
        if tid in vtypes:
            out[tid] = vtypes[tid]
        elif tid in BUILTIN_TYPES:
            out[tid] = make_vtype(tid, {"vClass": BUILTIN_TYPES[tid]})
        else:
            raise InputError(f"vType {tid!r} used in {source} has no size: pass the route "
                             f"or additional file that defines it with --vtypes")
    return out

"""A SUMO road network (``.net.xml``) read with sumolib into plain arrays.

sumolib is imported lazily (``pip install sumolib``; the command line's requirements
carry it). The network is read with its internal lanes, walking areas and crossings
(``readNet(withInternal=True, withPedestrianConnections=True)``). Coordinates are the
network's own: SUMO has already shifted them by ``<location netOffset=...>`` (the
offset is kept in ``RoadNetwork.net_offset`` so a scene can say where it came from).

What a lane is here (the ``kind`` of ``Lane``):

* ``walkingarea``: a lane of an edge with ``function="walkingarea"``; its shape is the
  walking area's outline (a polygon), not a centre line;
* ``crossing``: a lane of an edge with ``function="crossing"`` (centre line + width);
* ``sidewalk``: any other lane that allows pedestrians only (``allow="pedestrian"``);
* ``road``: every other lane, internal lanes (``function="internal"``) included.

A network with elevation (a lane or junction with z beyond ``FLAT_TOLERANCE_M``) is
refused: the scene's roads are flat at z = 0 (``netconvert --flatten`` removes z).
"""

import os
import xml.sax
import xml.sax.handler
from dataclasses import dataclass, field

import numpy as np

from ..errors import InputError

FLAT_TOLERANCE_M = 0.01
PEDESTRIAN = "pedestrian"
# SUMO's node types with traffic lights (sumo.dlr.de/docs/Networks/PlainXML.html,
# "Node types"); rail_signal is a railway's, not a road junction's.
SIGNALISED = ("traffic_light", "traffic_light_unregulated", "traffic_light_right_on_red")


@dataclass(frozen=True)
class Lane:
    id: str
    edge: str
    kind: str            # road, sidewalk, crossing, walkingarea
    shape: np.ndarray    # (n, 2) centre line (walkingarea: the outline)
    width: float
    internal: bool       # a lane inside a junction (internal, crossing, walking area)


@dataclass(frozen=True)
class Junction:
    id: str
    type: str
    centre: np.ndarray   # (2,) the node's position
    shape: np.ndarray    # (n, 2) outline, possibly empty
    roads: tuple = ()    # unit vectors from the centre along each road that meets here
    incoming_lanes: int = 0  # lanes of the edges that end here, sidewalks left out

    @property
    def signalised(self):
        return self.type in SIGNALISED


@dataclass
class RoadNetwork:
    path: str
    lanes: list
    junctions: list
    net_offset: tuple = (0.0, 0.0)
    by_id: dict = field(default_factory=dict)

    def junction(self, jid):
        return self.by_id.get(jid)


def import_sumolib():
    """sumolib, or an InputError saying how to install it."""
    try:
        import sumolib  # noqa: F401
        import sumolib.net
    except ImportError:
        raise InputError("SUMO's Python library is missing: pip install sumolib "
                         "(and eclipse-sumo for netconvert and netgenerate)") from None
    return sumolib


def _xy(points, what):
    arr = np.asarray(points, dtype=np.float64)
    if arr.size == 0:
        return np.zeros((0, 2))
    if arr.ndim != 2 or arr.shape[1] < 2 or not np.isfinite(arr).all():
        raise InputError(f"{what} has a malformed shape (a coordinate that is not a "
                         "finite number)")
    return arr


def _check_flat(points3d, what, path):
    arr = np.asarray(points3d, dtype=np.float64)
    if (arr.ndim == 2 and arr.shape[1] >= 3 and arr.size
            and np.abs(arr[:, 2]).max() > FLAT_TOLERANCE_M):
        z = float(np.abs(arr[:, 2]).max())
        raise InputError(f"{path}: {what} has elevation (|z| up to {z:.2f} m); rls scene from-net "
                         "builds flat roads at z = 0: rebuild the network with "
                         "'netconvert --sumo-net-file NET --flatten -o FLAT.net.xml'")


def lane_kind(function, permissions):
    if function == "walkingarea":
        return "walkingarea"
    if function == "crossing":
        return "crossing"
    if set(permissions) == {PEDESTRIAN}:
        return "sidewalk"
    return "road"


class _Root(xml.sax.ContentHandler):
    def __init__(self):
        super().__init__()
        self.root = None

    def startElement(self, name, attrs):
        if self.root is None:
            self.root = name


class _RootReached(Exception):
    pass


def refuse_internal_dtd(path):
    """``InputError`` when the XML file at ``path`` has an internal DTD (where entities
    are declared): SUMO writes none, and a file from elsewhere is read as data, with no
    entity of its own expanded (a few hundred bytes can otherwise expand to gigabytes).
    Reads only the file's prolog, up to its root element; a file that is not XML is left
    to its reader to name."""
    import xml.parsers.expat

    found = []

    def doctype(name, system_id, public_id, has_internal_subset):
        if has_internal_subset:
            found.append(name)
        raise _RootReached

    def start(name, attrs):
        raise _RootReached

    parser = xml.parsers.expat.ParserCreate()
    parser.StartDoctypeDeclHandler = doctype
    parser.StartElementHandler = start
    try:
        with open(path, "rb") as fh:
            while True:
                chunk = fh.read(1 << 16)
                parser.Parse(chunk, not chunk)
                if not chunk:
                    break
    except (_RootReached, xml.parsers.expat.ExpatError, OSError):
        pass
    if found:
        raise InputError(f"{path} declares its own DTD (<!DOCTYPE {found[0]} [...]>, where "
                         "entities are declared), which SUMO never writes: refused, nothing "
                         "in it is expanded")


def check_xml(path):
    """``InputError`` unless ``path`` is well-formed XML whose root element is <net>
    (one pass of Python's expat parser; external entities are not loaded, a file with
    an internal DTD is refused: ``refuse_internal_dtd``)."""
    refuse_internal_dtd(path)
    handler = _Root()
    parser = xml.sax.make_parser()
    parser.setFeature(xml.sax.handler.feature_external_ges, False)
    parser.setContentHandler(handler)
    try:
        parser.parse(path)
    except xml.sax.SAXParseException as exc:
        raise InputError(f"{path} is not a well-formed SUMO network (XML error at line "
                         f"{exc.getLineNumber()}: {exc.getMessage()}); is it truncated?") from None
    except OSError as exc:
        raise InputError(f"cannot read {path}: {exc.strerror or exc}") from None
    if handler.root != "net":
        raise InputError(f"{path} is not a SUMO network: its root element is <{handler.root}>, "
                         "not <net>")


def read_network(path):
    """The network at ``path`` as a ``RoadNetwork``; ``InputError`` when it is missing,
    not well-formed XML (truncated, say), not a SUMO network, or has elevation. The file
    is only read."""
    path = os.fspath(path)
    if not os.path.isfile(path):
        raise InputError(f"network file not found: {path}")
    sumolib = import_sumolib()
    check_xml(path)
    try:
        net = sumolib.net.readNet(path, withInternal=True, withPedestrianConnections=True)
    except (xml.sax.SAXException, KeyError, ValueError, TypeError, AttributeError,
            IndexError) as exc:
        raise InputError(f"{path} is not a SUMO network sumolib can read "
                         f"({type(exc).__name__}: {exc})") from None
    lanes = []
    for edge in net.getEdges(withInternal=True):
        function = edge.getFunction() or ""
        for lane in edge.getLanes():
            _check_flat(lane.getShape3D(), f"lane {lane.getID()}", path)
            kind = lane_kind(function, lane.getPermissions())
            if function == "internal" and _no_length(lane):
                # netconvert writes these where two edges meet end to end (a node with
                # no junction area: length 0.10, both points the same): no ground
                continue
            lanes.append(_lane(lane, edge, kind, function, path))
    junctions = []
    for node in net.getNodes():
        _check_defined(node, path)
        if node.getType() == "internal":
            continue
        _check_flat(node.getShape3D(), f"junction {node.getID()}", path)
        _check_flat([node.getCoord3D()], f"junction {node.getID()}", path)
        centre = np.asarray(node.getCoord()[:2], dtype=np.float64)
        roads = [_road_direction(e, centre, incoming)
                 for incoming, edges in ((True, node.getIncoming()), (False, node.getOutgoing()))
                 for e in edges if not e.getFunction()]
        lanes_in = sum(1 for e in node.getIncoming() if not e.getFunction()
                       for lane in e.getLanes()
                       if lane_kind("", lane.getPermissions()) == "road")
        junctions.append(Junction(id=node.getID(), type=node.getType(), centre=centre,
                                  shape=_xy(node.getShape(), f"junction {node.getID()}"),
                                  roads=tuple(r for r in roads if r is not None),
                                  incoming_lanes=lanes_in))
    offset = tuple(float(v) for v in net.getLocationOffset()[:2])
    return RoadNetwork(path=path, lanes=lanes, junctions=junctions, net_offset=offset,
                       by_id={j.id: j for j in junctions})


def _no_length(lane):
    shape = np.asarray(lane.getShape(), dtype=np.float64).reshape(-1, 2)
    return not np.any(np.linalg.norm(np.diff(shape, axis=0), axis=1) > 0)


def _lane(lane, edge, kind, function, path):
    """A ``Lane``; ``InputError`` for a width that is not a positive number or a centre
    line of fewer than two distinct points (a walking area's outline excepted): such a
    lane would be left out of the scene, and SUMO writes none but internal lanes (those
    are skipped by ``read_network``)."""
    lid = lane.getID()
    shape = _xy(lane.getShape(), f"{path}: lane {lid}")
    width = float(lane.getWidth())
    if not (np.isfinite(width) and width > 0):
        raise InputError(f"{path}: lane {lid} has width {lane.getWidth()!r}: a lane needs a "
                         "positive width in metres")
    if kind != "walkingarea":
        steps = np.linalg.norm(np.diff(shape, axis=0), axis=1) if len(shape) > 1 else []
        if not np.any(np.asarray(steps) > 0):
            raise InputError(f"{path}: lane {lid} has a shape of {len(shape)} point(s) "
                             "but no length: a lane's centre line needs two distinct points")
    return Lane(id=lid, edge=edge.getID(), kind=kind, shape=shape, width=width,
                internal=bool(function))


def _check_defined(node, path):
    """``InputError`` for a junction that edges name but no ``<junction>`` defines
    (sumolib makes it without a position)."""
    try:
        node.getCoord()
    except TypeError:
        edges = [e.getID() for e in node.getIncoming() + node.getOutgoing()]
        raise InputError(f"{path}: junction {node.getID()!r} is named by edge "
                         f"{edges[0] if edges else '?'!r} but has no <junction> element: "
                         "is the network cut short or edited by hand? Write it again "
                         "with netconvert") from None


ROAD_PROBE_M = 30.0


def _road_direction(edge, centre, incoming):
    """Unit vector from the junction's centre towards the point ``ROAD_PROBE_M`` metres
    along the edge from the junction (its end for an incoming edge, its start for an
    outgoing one), or None for an edge of no length."""
    shape = np.asarray(edge.getShape(), dtype=np.float64)[:, :2]
    if incoming:
        shape = shape[::-1]
    seg = np.linalg.norm(np.diff(shape, axis=0), axis=1)
    s = np.r_[0.0, np.cumsum(seg)]
    if s[-1] <= 0:
        return None
    t = min(ROAD_PROBE_M, s[-1])
    p = np.array([np.interp(t, s, shape[:, 0]), np.interp(t, s, shape[:, 1])])
    d = p - centre
    n = np.linalg.norm(d)
    return d / n if n > 1e-9 else None

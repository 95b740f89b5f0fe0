"""SUMO floating-car data: reading (streamed, bad files refused with the line), the
conversion from SUMO's front-bumper position and navigational angle to a box centre and
Blender yaw (hand-computed cases), resampling at a frame rate (linear, shorter arc, never
extrapolated) and vType sizes (SUMO's vClass defaults, from its source)."""

import math

import numpy as np
import pytest

from rls_addon.core.errors import InputError
from rls_addon.core.traffic.fcd import (
    box_centre,
    frame_times,
    load,
    read_fcd,
    resample,
    yaw_of_angle,
)
from rls_addon.core.traffic.sumo_run import sibling, strip_header, vtypes_xml
from rls_addon.core.traffic.vtypes import VCLASS_DEFAULTS, read_vtypes, resolve

FCD = """<?xml version="1.0" encoding="UTF-8"?>
<!-- generated on a date by Eclipse SUMO sumo 1.28.0 -->
<fcd-export>
    <timestep time="0.00">
        <vehicle id="a" x="10.00" y="0.00" angle="90.00" type="car" speed="10" pos="5" lane="e_0" slope="0.00"/>
    </timestep>
    <timestep time="1.00">
        <vehicle id="a" x="20.00" y="0.00" angle="90.00" type="car" speed="10" pos="15" lane="e_0" slope="0.00"/>
        <person id="p" x="0.00" y="5.00" angle="0.00" type="DEFAULT_PEDTYPE" speed="1" pos="1" edge="e"/>
    </timestep>
    <timestep time="2.00">
        <vehicle id="a" x="30.00" y="0.00" angle="350.00" type="car" speed="10" pos="25" lane="e_0" slope="0.00"/>
        <person id="p" x="0.00" y="6.00" angle="0.00" type="DEFAULT_PEDTYPE" speed="1" pos="2" edge="e"/>
    </timestep>
    <timestep time="3.00">
        <vehicle id="a" x="40.00" y="0.00" angle="10.00" type="car" speed="10" pos="35" lane="e_0" slope="0.00"/>
    </timestep>
    <timestep time="4.00"/>
</fcd-export>
"""
VTYPES = """<routes>
    <vType id="car" vClass="passenger" length="4.00" width="2.00" height="1.40"/>
    <vType id="lorry" vClass="truck"/>
    <vehicle id="x" type="car" depart="0"><route edges="e"/></vehicle>
</routes>
"""


@pytest.fixture
def files(tmp_path):
    f = tmp_path / "run.xml"
    f.write_text(FCD)
    v = tmp_path / "types.rou.xml"
    v.write_text(VTYPES)
    return f, v


def test_reads_tracks_in_time_order(files):
    fcd = read_fcd(str(files[0]))
    assert set(fcd.tracks) == {"a", "person:p"}
    assert fcd.step == pytest.approx(1.0) and (fcd.first, fcd.last) == (0.0, 4.0)
    a = fcd.tracks["a"]
    assert a.kind == "vehicle" and a.type == "car"
    assert list(a.times) == [0, 1, 2, 3] and list(a.x) == [10, 20, 30, 40]
    assert fcd.tracks["person:p"].kind == "person"
    assert fcd.types == {"car", "DEFAULT_PEDTYPE"}


def test_conversion_hand_computed():
    # angle 0: north (+y) -> yaw 90 deg; 90: east (+x) -> yaw 0; 180: south; 270: west
    assert np.degrees(yaw_of_angle([0, 90, 180, 270, 45])) == pytest.approx(
        [90, 0, -90, -180, 45])
    # a 4 m car heading east with its front bumper at (10, 0): centre 2 m behind, (8, 0)
    cx, cy, yaw = box_centre([10.0], [0.0], [90.0], 4.0)
    assert (cx[0], cy[0], yaw[0]) == pytest.approx((8.0, 0.0, 0.0))
    # heading north-east (45 deg): centre at front - 2 (cos 45, sin 45)
    cx, cy, _ = box_centre([10.0], [10.0], [45.0], 4.0)
    assert (cx[0], cy[0]) == pytest.approx((10 - math.sqrt(2), 10 - math.sqrt(2)))
    # heading south with origin (100, 50): (100, 50) lands on the scene's origin
    cx, cy, yaw = box_centre([103.0], [60.0], [180.0], 12.0, origin=(100.0, 50.0))
    assert (cx[0], cy[0], math.degrees(yaw[0])) == pytest.approx((3.0, 16.0, -90.0))


def test_resample_linear_shorter_arc_no_extrapolation(files):
    fcd = read_fcd(str(files[0]))
    times = frame_times(9, 2.0, -0.5)        # -0.5, 0, 0.5, ... 3.5 s
    m = resample(fcd.tracks["a"], 4.0, times, fcd.step, origin=(1.0, 0.0))
    # present from 0 s (frame 1) to 3 s (frame 7): not before, not after (no extrapolation)
    assert (m.first, m.stop) == (1, 8) and m.present.all()
    # at 0.5 s the front is at x=15 heading east: centre 13, minus the origin's 1
    assert m.xyz[1] == pytest.approx([12.0, 0.0, 0.0])
    # 2 s -> 3 s turns from 350 to 10 deg by the shorter arc (through 0): at 2.5 s, 0 deg
    # navigational, yaw 90 deg; continuous over frames
    assert math.degrees(m.yaw[5]) % 360 == pytest.approx(90.0)
    assert np.all(np.abs(np.diff(m.yaw)) <= math.radians(50) + 1e-9)  # 100 deg a step at most
    # centre at 2.5 s: the interpolated centres of 2 s and 3 s
    c2 = box_centre([30.0], [0.0], [350.0], 4.0, (1.0, 0.0))
    c3 = box_centre([40.0], [0.0], [10.0], 4.0, (1.0, 0.0))
    assert m.xyz[5][:2] == pytest.approx([(c2[0][0] + c3[0][0]) / 2, (c2[1][0] + c3[1][0]) / 2])
    # times past its span: None
    assert resample(fcd.tracks["a"], 4.0, frame_times(3, 1.0, 5.0), fcd.step) is None


def test_gap_in_a_track_is_absent(tmp_path):
    f = tmp_path / "gap.xml"
    f.write_text('<fcd-export><timestep time="0"><vehicle id="a" x="0" y="0" angle="90" '
                 'type="car"/></timestep><timestep time="1"/><timestep time="2"/>'
                 '<timestep time="3"><vehicle id="a" x="30" y="0" angle="90" type="car"/>'
                 '</timestep></fcd-export>')
    fcd = read_fcd(str(f))
    m = resample(fcd.tracks["a"], 4.0, frame_times(4, 1.0, 0.0), fcd.step)
    assert list(m.present) == [True, False, False, True]
    assert m.xyz[1] == pytest.approx(m.xyz[0])   # held in the gap, never extrapolated


# SUMO 1.28's output of a person riding car "c" (a <ride> stage), then walking off:
# the rider is written right after its vehicle at the vehicle's own position (its front
# bumper; MSFCDExport::write), as a sibling <person>, not a child.
FCD_RIDE = """<fcd-export>
    <timestep time="0.00">
        <vehicle id="c" x="4.70" y="95.20" angle="90.00" type="car" speed="13.90" pos="4.70" lane="WC_1" slope="0.00"/>
        <person id="r" x="4.70" y="95.20" angle="90.00" type="ped" speed="13.90" pos="4.70" edge="WC" slope="0.00"/>
        <person id="w" x="108.00" y="0.00" angle="0.00" type="ped" speed="0.00" pos="0.00" edge="SC" slope="0.00"/>
    </timestep>
    <timestep time="1.00">
        <vehicle id="c" x="18.52" y="95.20" angle="90.00" type="car" speed="13.82" pos="18.52" lane="WC_1" slope="0.00"/>
        <person id="r" x="18.52" y="95.20" angle="90.00" type="ped" speed="13.82" pos="18.52" edge="WC" slope="0.00" vehicle="c"/>
        <person id="w" x="108.00" y="1.29" angle="0.00" type="ped" speed="1.29" pos="1.29" edge="SC" slope="0.00" vehicle=""/>
    </timestep>
    <timestep time="2.00">
        <vehicle id="c" x="30.00" y="95.20" angle="90.00" type="car" speed="0.00" pos="30.00" lane="WC_1" slope="0.00"/>
        <person id="r" x="29.00" y="97.00" angle="0.00" type="ped" speed="1.00" pos="29.00" edge="WC" slope="0.00"/>
    </timestep>
</fcd-export>
"""


def test_a_person_riding_a_vehicle_is_not_a_pedestrian(tmp_path):
    """A riding person's samples (at its vehicle's x, y, or naming a vehicle) are left
    out: it was keyed as a pedestrian standing in the car's front bumper. Walking, it
    is read as before."""
    f = tmp_path / "ride.xml"
    f.write_text(FCD_RIDE)
    fcd = read_fcd(str(f))
    r, w = fcd.tracks["person:r"], fcd.tracks["person:w"]
    assert list(r.times) == [2.0] and (r.x[0], r.y[0]) == (29.0, 97.0)
    assert list(w.times) == [0.0, 1.0] and list(w.y) == [0.0, 1.29]
    assert list(fcd.tracks["c"].times) == [0.0, 1.0, 2.0]


def test_fcd_in_utm_coordinates_is_refused(tmp_path):
    """``--fcd-output.utm`` writes vehicles in unshifted coordinates (network - its
    netOffset; SUMO 1.28 leaves persons in the network's): keyed, they missed the roads
    by the netOffset (900, 1900 m on a plain network). SUMO's header names the option."""
    f = tmp_path / "utm.xml"
    f.write_text('<?xml version="1.0" encoding="UTF-8"?>\n\n<!-- generated on 2026 by '
                 'Eclipse SUMO sumo 1.28.0\n<sumoConfiguration>\n    <output>\n        '
                 '<fcd-output value="utm.xml"/>\n        <fcd-output.utm value="true"/>\n'
                 '    </output>\n</sumoConfiguration>\n-->\n\n<fcd-export>\n'
                 '<timestep time="0.00"><vehicle id="a" x="1001.60" y="1904.70" '
                 'angle="0.00" type="car"/></timestep></fcd-export>\n')
    with pytest.raises(InputError, match="--fcd-output.utm"):
        read_fcd(str(f))
    f.write_text(f.read_text().replace('utm value="true"', 'utm value="false"'))
    assert set(read_fcd(str(f)).tracks) == {"a"}


def test_not_xml_and_truncated_name_the_line(tmp_path, files):
    bad = tmp_path / "bad.xml"
    bad.write_bytes(b"\x00\x01 not xml at all")
    with pytest.raises(InputError, match="line 1"):
        read_fcd(str(bad))
    cut = tmp_path / "cut.xml"
    cut.write_text(FCD[: FCD.index("<timestep time=\"2.00\">") + 40])
    with pytest.raises(InputError, match=r"not complete.*line \d+"):
        read_fcd(str(cut))
    other = tmp_path / "other.xml"
    other.write_text("<routes/>")
    with pytest.raises(InputError, match="not SUMO FCD output"):
        read_fcd(str(other))
    with pytest.raises(InputError, match="not found"):
        read_fcd(str(tmp_path / "none.xml"))


def test_vtypes_sizes_defaults_and_errors(files, tmp_path):
    types = read_vtypes(str(files[1]))
    assert types["car"].size == (4.0, 2.0, 1.4) and types["car"].label == "vehicle"
    # attributes left out take SUMO's vClass defaults (SUMOVTypeParameter.cpp: truck
    # 2.4 x 2.4, getDefaultVehicleLength 7.1)
    assert types["lorry"].size == (7.1, 2.4, 2.4) and types["lorry"].shape == "truck"
    got = resolve({"car", "DEFAULT_PEDTYPE", "DEFAULT_BIKETYPE"}, types)
    assert got["DEFAULT_PEDTYPE"].size == (0.215, 0.478, 1.719)
    assert got["DEFAULT_PEDTYPE"].label == "pedestrian"
    assert got["DEFAULT_BIKETYPE"].size == (1.6, 0.65, 1.7)
    assert got["DEFAULT_BIKETYPE"].label == "cyclist"
    with pytest.raises(InputError, match="'mystery'.*no size.*--vtypes"):
        resolve({"mystery"}, types)
    zero = tmp_path / "zero.xml"
    zero.write_text('<routes><vType id="flat" length="0"/></routes>')
    with pytest.raises(InputError, match="'flat' has length '0'"):
        read_vtypes(str(zero))
    assert VCLASS_DEFAULTS["passenger"] == (5.0, 1.8, 1.5)


def test_vclass_defaults_are_sumo_1_28s(tmp_path):
    """The sizes SUMO 1.28.0 gives a vType that names only its vClass (read back from
    the running simulation with TraCI's vehicletype.getLength/getWidth/getHeight): a
    scooter and a wheelchair were 5 m long (SUMO: 1.2 m; the wheelchair 0.8 x 1.5, SUMO
    0.72 x 1.2), and SUMO's "evehicle" was refused as unknown ("e_vehicle", which SUMO
    refuses)."""
    sumo_1_28 = {"scooter": (1.2, 0.5, 1.7), "wheelchair": (1.2, 0.72, 1.2),
                 "evehicle": (5.0, 1.8, 1.5), "moped": (2.1, 0.78, 1.7),
                 "motorcycle": (2.2, 0.9, 1.5), "delivery": (6.5, 2.16, 2.86),
                 "bicycle": (1.6, 0.65, 1.7), "pedestrian": (0.215, 0.478, 1.719)}
    f = tmp_path / "classes.add.xml"
    f.write_text("<additional>" + "".join(f'<vType id="t_{c}" vClass="{c}"/>'
                                          for c in sumo_1_28) + "</additional>")
    types = read_vtypes(str(f))
    assert {c: types[f"t_{c}"].size for c in sumo_1_28} == sumo_1_28
    assert "e_vehicle" not in VCLASS_DEFAULTS


def test_a_person_of_a_vehicle_class_is_refused(tmp_path):
    """SUMO 1.28 gives a person whose vType names no vClass the passenger class and a
    5 m body (read back with TraCI's vehicletype.getVehicleClass/getLength; SUMO warns
    'Person ... receives type ... which implicitly uses unsuitable vClass'). RLS keyed
    it as a car-sized vehicle walking the sidewalk; it is refused, naming the fix."""
    fcd = tmp_path / "walk.xml"
    fcd.write_text(FCD.replace('type="DEFAULT_PEDTYPE"', 'type="walker"'))
    types = tmp_path / "walk.rou.xml"
    types.write_text('<routes><vType id="car" vClass="passenger"/><vType id="walker"/>'
                     '</routes>')
    with pytest.raises(InputError, match=r"persons walk with vType 'walker', whose vClass "
                       r"is 'passenger'.*5 m body.*vClass=\"pedestrian\" and run SUMO"):
        load(str(fcd), [str(types)])
    for ok in ("pedestrian", "wheelchair"):
        types.write_text(f'<routes><vType id="car" vClass="passenger"/><vType id="walker" '
                         f'vClass="{ok}"/></routes>')
        assert load(str(fcd), [str(types)])[1]["walker"].label == "pedestrian"


def test_load_finds_vtypes_beside_the_fcd(tmp_path):
    fcd = tmp_path / "busy.xml"
    fcd.write_text(FCD.replace('type="car"', 'type="rls_car"'))
    with pytest.raises(InputError, match="'rls_car'.*no size"):
        load(str(fcd))
    (tmp_path / "busy.vtypes.xml").write_text(vtypes_xml())
    _, types = load(str(fcd))
    assert types["rls_car"].size == (4.6, 1.8, 1.5)
    assert sibling("a/b.xml", ".rou.xml") == "a/b.rou.xml"


def test_strip_header_drops_sumo_comment_only():
    data = FCD.encode()
    out = strip_header(data)
    assert b"generated on" not in out and out.startswith(b"<?xml") and b"<fcd-export>" in out
    assert strip_header(b"<a><!-- keep --></a>") == b"<a><!-- keep --></a>"


def test_bad_values_named(tmp_path):
    f = tmp_path / "nan.xml"
    f.write_text('<fcd-export><timestep time="0"><vehicle id="a" x="abc" y="0" angle="0" '
                 'type="car"/></timestep></fcd-export>')
    with pytest.raises(InputError, match="id='a'.*not a number"):
        read_fcd(str(f))
    f.write_text('<fcd-export><timestep time="0"><vehicle id="a" y="0" angle="0" '
                 'type="car"/></timestep></fcd-export>')
    with pytest.raises(InputError, match="has no 'x'"):
        read_fcd(str(f))
    f.write_text('<fcd-export></fcd-export>')
    with pytest.raises(InputError, match="no <timestep>"):
        read_fcd(str(f))


def test_how_frames_map_to_sumo_steps_is_said():
    """One frame per step says nothing; otherwise the mapping is named with the fps
    that would make it one to one."""
    from rls_addon.core.traffic.fcd import step_notice

    assert step_notice(10, 0.1, 0.0, 1) is None
    assert step_notice(10.0, 0.1 + 1e-9, 5.0, 1) is None
    slow = step_notice(24, 0.1, 60.0, 1)
    assert "step is 0.1 s" in slow and "24 fps" in slow and "2.4 frames" in slow
    assert "60 + (f - 1) / 24 s" in slow and "10 fps" in slow
    coarse = step_notice(10, 1.0, 0.0, 1)
    assert "10 frames" in coarse and "set the scene to 1 fps" in coarse
    assert "steps apart" in step_notice(5, 0.1, 0.0, 1)


def test_ground_surface_heights():
    """The first ground surface down from STEP_M above FCD's z, within 2 STEP_M; else
    FCD's z (exact numpy caster; two stacked squares: 0.15 m over x >= 0, 3 m over
    x >= 5, a level too far above a z of 0 to step onto)."""
    from rls_addon.core.casting import NumpyCaster
    from rls_addon.core.traffic.ground import STEP_M, GroundSurface

    quads = [(0.0, 0.15), (5.0, 3.0)]
    v, t = [], []
    for x0, z in quads:
        k = len(v)
        v += [(x0, -1, z), (10, -1, z), (10, 1, z), (x0, 1, z)]
        t += [(k, k + 1, k + 2), (k, k + 2, k + 3)]
    g = GroundSurface(np.array(v, float), np.array(t), NumpyCaster)
    xy = np.array([(-1.0, 0.0), (1.0, 0.0), (6.0, 0.0), (6.0, 0.0), (1.0, 5.0)])
    z = np.array([0.0, 0.0, 0.0, 2.8, 0.0])
    assert g.heights(xy, z) == pytest.approx([0.0, 0.15, 0.15, 3.0, 0.0])
    assert STEP_M == 0.5
    assert GroundSurface(np.zeros((0, 3)), np.zeros((0, 3)), NumpyCaster).heights(
        xy, 0.25) == pytest.approx([0.25] * 5)

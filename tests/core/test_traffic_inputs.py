"""Bad SUMO inputs (issue #38): each FCD fault, origin, time range and generate option
ends in one InputError naming the line, time, object or flag, never a silent wrong
scene; values float32 keys cannot hold are refused with the limit named; generate's
outputs are written as a set."""

import errno

import numpy as np
import pytest

from rls_addon.core.errors import InputError, OutputError
from rls_addon.core.traffic import sumo_run
from rls_addon.core.traffic import fcd as fcd_module
from rls_addon.core.traffic.fcd import load, read_fcd

HEAD = '<?xml version="1.0" encoding="UTF-8"?>\n<fcd-export>\n'
TAIL = "</fcd-export>\n"


def veh(vid="a", x=10.0, y=0.0, angle=90.0, typ="DEFAULT_VEHTYPE"):
    return (f'        <vehicle id="{vid}" x="{x}" y="{y}" angle="{angle}" type="{typ}" '
            f'speed="1" pos="1" lane="e_0"/>\n')


def fcd(tmp_path, *steps):
    """An FCD file of ``steps``: (time, [vehicle lines])."""
    body = "".join(f'    <timestep time="{t}">\n' + "".join(objs) + "    </timestep>\n"
                   for t, objs in steps)
    path = tmp_path / "run.xml"
    path.write_text(HEAD + body + TAIL)
    return str(path)


def test_a_repeated_timestep_is_refused_naming_it(tmp_path):
    path = fcd(tmp_path, ("0.00", [veh(x=1)]), ("0.10", [veh(x=2)]), ("0.10", [veh(x=9)]))
    with pytest.raises(InputError, match=r"time='0.10'.*repeats the timestep before it"):
        read_fcd(path)
    path = fcd(tmp_path, ("0.00", [veh(x=1)]), ("0.20", [veh(x=2)]), ("0.10", [veh(x=3)]))
    with pytest.raises(InputError, match=r"time='0.10'.*goes back in time after time=0.2"):
        read_fcd(path)


def test_one_id_twice_in_a_timestep_is_refused(tmp_path):
    path = fcd(tmp_path, ("0.00", [veh(x=1)]), ("0.10", [veh(x=2), veh(x=40)]))
    with pytest.raises(InputError, match=r"id='a'> appears twice in the timestep at time 0.1"):
        read_fcd(path)


def test_a_type_that_changes_is_refused(tmp_path):
    path = fcd(tmp_path, ("0.00", [veh()]), ("0.10", [veh(typ="DEFAULT_BIKETYPE")]))
    with pytest.raises(InputError, match=r"id='a'> changes its type from 'DEFAULT_VEHTYPE' "
                                         r"to 'DEFAULT_BIKETYPE' at time 0.1"):
        read_fcd(path)


def test_an_angle_of_1e20_degrees_is_refused_with_the_limit(tmp_path):
    path = fcd(tmp_path, ("0.00", [veh()]), ("0.10", [veh(angle="1e20")]))
    with pytest.raises(InputError, match=r"at time 0.1 has angle 1e\+20.*within \+-3600"):
        read_fcd(path)


@pytest.mark.parametrize("x", ["1e300", "1e12"])
def test_positions_float32_cannot_key_are_refused_with_the_limit(tmp_path, x):
    """1e300 overflows float32 (3.4e38 at most); at 1e12 float32's step is 65,536 m, so
    a 1 m motion is lost: both refused, naming the object, time and the 1e5 m limit.
    With the origin at 1e12 the same motion is near the scene's origin: kept."""
    path = fcd(tmp_path, ("0.00", [veh(x=x)]), ("0.10", [veh(x=f"{float(x) + 1:.17g}")]))
    f, types = load(path)
    check_positions = fcd_module.check_positions
    with pytest.raises(InputError, match=r"id='a'> at time [0-9.]+ lies .* m from the scene's "
                                         r"origin: RLS takes coordinates within 100000 m"):
        check_positions(f, types, (0.0, 0.0))
    if x == "1e12":
        check_positions(f, types, (1e12, 0.0))
        tr = f.tracks["a"]
        assert tr.x[1] - tr.x[0] == pytest.approx(1.0)


def test_origin_and_times_that_are_not_numbers_are_named(tmp_path):
    path = fcd(tmp_path, ("0.00", [veh()]), ("0.10", [veh(x=11)]))
    with pytest.raises(InputError, match=r"--begin nan is not a number of seconds"):
        load(path, begin=float("nan"))
    with pytest.raises(InputError, match=r"--end inf is not a number of seconds"):
        load(path, end=float("inf"))
    check_origin = fcd_module.check_origin
    with pytest.raises(InputError, match=r"--origin nan 0: the origin's x and y must be "
                                         r"finite"):
        check_origin((float("nan"), 0.0))
    check_origin((3.0, -4.0))
    check_origin(None)


def test_a_stretch_past_blenders_last_frame_is_refused(tmp_path):
    path = fcd(tmp_path, ("0.00", [veh()]), ("200000.00", [veh(x=11)]))
    f, _ = load(path)
    keyed_frames, MAX_FRAME = fcd_module.keyed_frames, 1_048_574
    assert keyed_frames(f, 5, 1) == (0.0, 200000.0, 1_000_001)
    with pytest.raises(InputError, match=rf"past Blender's last frame \({MAX_FRAME}\)"):
        keyed_frames(f, 10, 1)


@pytest.mark.parametrize("kw, words", [
    ({"step": float("nan")}, r"--step nan: must be a positive number"),
    ({"duration": float("inf")}, r"--duration inf: must be a positive number"),
    ({"rate": -5.0}, r"--rate -5.0: must be a positive number"),
    ({"ped_rate": 0.0}, r"--ped-rate 0.0: must be a positive number"),
    ({"seed": 12345678901234567890}, r"--seed 12345678901234567890: SUMO takes seeds from 0 "
                                     r"to 2147483647"),
])
def test_generate_names_the_option_sumo_would_fail_on(tmp_path, kw, words):
    net = tmp_path / "n.net.xml"
    net.write_text("<net/>")
    args = dict(duration=10.0, rate=100.0, seed=1, step=0.1)
    args.update(kw)
    with pytest.raises(InputError, match=words):
        sumo_run.generate(str(net), str(tmp_path / "out.xml"), **args)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["n.net.xml"]


def fake_sumo(tmp_path, monkeypatch):
    """A SUMO install whose programs write small outputs (no SUMO needed)."""
    home = tmp_path / "sumo"
    (home / "bin").mkdir(parents=True)
    (home / "tools").mkdir()
    (home / "bin" / "sumo").write_text("")
    (home / "tools" / "randomTrips.py").write_text("")
    monkeypatch.setattr(sumo_run, "sumo_home", lambda: str(home))

    def run(cmd, env, what):
        if "-r" in cmd:
            with open(cmd[cmd.index("-r") + 1], "w") as fh:
                fh.write('<routes>\n<vehicle id="v0" depart="0"/>\n</routes>\n')
        if "--fcd-output" in cmd:
            with open(cmd[cmd.index("--fcd-output") + 1], "w") as fh:
                fh.write(HEAD + TAIL)

    monkeypatch.setattr(sumo_run, "_run", run)


def test_generate_writes_its_outputs_as_a_set(tmp_path, monkeypatch):
    """The disk fills while the third output is written: none of the three is left
    (the routes and vTypes were left without the FCD before)."""
    fake_sumo(tmp_path, monkeypatch)
    net = tmp_path / "n.net.xml"
    net.write_text("<net/>")
    out = tmp_path / "out" / "traffic.xml"
    out.parent.mkdir()
    from rls_addon.core.output.io import atomic

    real_fsync, calls = atomic.os.fsync, []

    def fsync(fd):
        calls.append(fd)
        if len(calls) == 3:
            raise OSError(errno.ENOSPC, "No space left on device")
        real_fsync(fd)

    monkeypatch.setattr(atomic.os, "fsync", fsync)
    with pytest.raises(OutputError, match="disk full"):
        sumo_run.generate(str(net), str(out), 10.0, 100.0, 1, pedestrians="no")
    assert list(out.parent.iterdir()) == []
    monkeypatch.setattr(atomic.os, "fsync", real_fsync)
    info = sumo_run.generate_traffic(sumo_run.GenerateSettings(
        str(net), str(out), 10.0, 100.0, 1, pedestrians="no"))
    assert sorted(p.name for p in out.parent.iterdir()) == [
        "traffic.rou.xml", "traffic.vtypes.xml", "traffic.xml"]
    assert info["vehicles"] == 1
    assert np.isfinite(info["sumo_s"])


def test_reading_a_long_fcd_reports_its_progress(tmp_path):
    """2,000 timesteps: the share of the file read is reported every PROGRESS_STEPS
    steps, increasing, up to the end (the 100,000-step import was silent)."""
    steps = [(f"{k / 10:.2f}", [veh(x=k * 0.1)]) for k in range(2000)]
    path = fcd(tmp_path, *steps)
    shares = []
    f = read_fcd(path, progress=shares.append)
    assert len(shares) == 2000 // fcd_module.PROGRESS_STEPS
    assert shares == sorted(shares) and 0 < shares[0] and shares[-1] <= 1.0
    assert shares[-1] > 0.9 and len(f.tracks["a"].times) == 2000


# an entity of 200 kB referenced 90 times: 18 MB that expat's own guard (100x) lets
# through; a declared entity of any size is refused before it is read
ENTITY_DTD = ('<?xml version="1.0"?>\n<!DOCTYPE fcd-export [\n<!ENTITY e "' + "x" * 200_000
              + '">\n]>\n')


def test_an_internal_dtd_is_refused_nothing_expanded(tmp_path):
    from rls_addon.core.roads.network import check_xml
    from rls_addon.core.traffic.vtypes import read_vtypes

    path = fcd(tmp_path, ("0.00", [veh(typ="&e;" * 90)]), ("0.10", [veh(typ="&e;" * 90)]))
    with open(path) as fh:
        text = fh.read().replace('<?xml version="1.0" encoding="UTF-8"?>\n', ENTITY_DTD)
    with open(path, "w") as fh:
        fh.write(text)
    with pytest.raises(InputError, match=r"run\.xml declares its own DTD.*nothing in it is "
                                         r"expanded") as exc:
        read_fcd(path)
    assert len(str(exc.value)) < 300
    vtypes = tmp_path / "types.xml"
    vtypes.write_text(ENTITY_DTD.replace("fcd-export", "additional")
                      + '<additional><vType id="&e;" length="4"/></additional>\n')
    with pytest.raises(InputError, match="declares its own DTD"):
        read_vtypes(str(vtypes))
    net = tmp_path / "x.net.xml"
    net.write_text(ENTITY_DTD.replace("fcd-export", "net") + '<net version="1.9">&e;</net>\n')
    with pytest.raises(InputError, match="declares its own DTD"):
        check_xml(str(net))
    with pytest.raises(InputError, match="declares its own DTD"):
        sumo_run.has_sidewalks(str(net))
    # a DOCTYPE without an internal subset is not refused (nothing to expand)
    plain = tmp_path / "plain.xml"
    plain.write_text('<?xml version="1.0"?>\n<!DOCTYPE fcd-export>\n' + HEAD.split("\n", 1)[1]
                     + '<timestep time="0">' + veh() + "</timestep>" + TAIL)
    assert read_fcd(str(plain)).tracks

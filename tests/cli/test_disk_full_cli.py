"""A scene written onto a disk that fills during Blender's save (issue 38): ``rls scene
from-net`` and ``rls traffic import`` end with one ``rls: error:`` line and exit 1, and
leave nothing in the folder (Blender's save returned after writing 200 KiB of a ~260 KB
file, and the commands placed it and exited 0).

How the disk fills, for real: each command runs in a private mount namespace
(util-linux ``unshare --mount``; as root, as CI runs ``make test``, or as a mapped root in
a user namespace where those are allowed) with a 200 KiB tmpfs mounted on its output
folder; the scenes written are about 260 KB. The tmpfs lives and dies with the
namespace: nothing is mounted on the machine for the test, and nothing stays mounted
if it fails."""

import os
import shutil
import subprocess
import sys

import pytest

from tests.core.external_tools import missing
from tests.sumo_nets import ONE_CAR_FCD, grid_net

from .conftest import ROOT, outcome_lines, rls

TMPFS_KIB = 200
# inside the namespace: the tmpfs on $1, the command, then what it left in $1 into $2
SCRIPT = ('mount -t tmpfs -o size={kib}k rls-test "$1" || exit 90; dir=$1; listing=$2; '
          'shift 2; "$@"; rc=$?; ls -A "$dir" > "$listing"; exit $rc')


def namespace():
    """The ``unshare`` command line of a private mount namespace, or a skip (a failure
    under RLS_REQUIRE_TOOLS=1) saying why there is none."""
    if shutil.which("unshare") is None:
        missing("command 'unshare' is missing: apt-get install util-linux")
    cmd = ["unshare", "--mount", "--propagation", "private"] if os.geteuid() == 0 else \
        ["unshare", "--user", "--map-root-user", "--mount"]
    probe = subprocess.run(cmd + ["sh", "-c", "mount -t tmpfs -o size=64k t /mnt 2>/dev/null "
                                  "|| mount -t tmpfs -o size=64k t /tmp"],
                           capture_output=True, text=True)
    if probe.returncode != 0:
        missing("a small tmpfs cannot be mounted here (run the tests as root, as make test "
                f"does in CI): {probe.stderr.strip()[:200]}")
    return cmd


def on_full_disk(tmp_path, *args):
    """Run ``python -m rls_addon ARGS`` (``{out}`` in them: the tmpfs folder) with the
    tmpfs mounted; (CompletedProcess, what the folder held afterwards)."""
    folder, listing = tmp_path / "full", tmp_path / "listing.txt"
    folder.mkdir(parents=True)
    env = dict(os.environ, PYTHONPATH=str(ROOT))
    argv = [str(a).replace("{out}", str(folder)) for a in args]
    proc = subprocess.run(namespace() + ["sh", "-c", SCRIPT.format(kib=TMPFS_KIB), "sh",
                                         str(folder), str(listing), sys.executable, "-m",
                                         "rls_addon", *argv],
                          cwd=ROOT, env=env, capture_output=True, text=True, timeout=600)
    assert proc.returncode != 90, proc.stderr
    return proc, listing.read_text().split()


def the_error(proc):
    """The one line besides progress lines; it must be an error."""
    lines = outcome_lines(proc.stderr)
    assert len(lines) == 1 and lines[0].startswith("rls: error: "), proc.stderr
    return lines[0]


@pytest.fixture(scope="module")
def net(tmp_path_factory):
    return grid_net(tmp_path_factory.mktemp("net"))


def test_from_net_and_traffic_import_onto_a_full_disk(net, tmp_path):
    proc, left = on_full_disk(tmp_path / "a", "scene", "from-net", net, "--out",
                              "{out}/scene.blend")
    assert proc.returncode == 1 and left == [], (proc.returncode, left, proc.stderr)
    err = the_error(proc)
    assert "scene.blend" in err and "incomplete file" in err and "free some space" in err
    assert proc.stdout == ""

    scene = tmp_path / "scene.blend"  # the same scene on a disk with room
    assert rls("scene", "from-net", net, "--out", scene).returncode == 0
    fcd = tmp_path / "fcd.xml"
    fcd.write_text(ONE_CAR_FCD)
    proc, left = on_full_disk(tmp_path / "b", "traffic", "import", scene, "--fcd", fcd, "--out",
                              "{out}/traffic.blend")
    assert proc.returncode == 1 and left == [], (proc.returncode, left, proc.stderr)
    err = the_error(proc)
    assert "traffic.blend" in err and "incomplete file" in err
    # and with room, the same import writes a whole scene
    room = tmp_path / "traffic.blend"
    assert rls("traffic", "import", scene, "--fcd", fcd, "--out", room).returncode == 0
    from rls_addon.core.output.io.blend_file import incomplete_blend

    assert incomplete_blend(room) is None and room.stat().st_size > TMPFS_KIB * 1024

"""Build and run tests/core/native/pcl_typed_reader.cpp: PCL's typed PCD loader with the
point structs of the ROS LiDAR drivers.

The program is compiled once per test session against Debian's ``libpcl-dev``. Where the
compiler or PCL's headers are missing the tests skip, saying what to install (``make
system-deps`` installs both), and fail under ``make test`` (``RLS_REQUIRE_TOOLS=1``); a
program that does not compile fails the test.
"""

import os
import pathlib
import shutil
import subprocess

import numpy as np

from .external_tools import missing

SOURCE = pathlib.Path(__file__).parent / "native" / "pcl_typed_reader.cpp"
# Debian packages: the C++ compiler, pkg-config and PCL's headers and libraries.
APT_PACKAGES = "g++ pkgconf libpcl-dev"


def _skip(what):
    missing(f"{what}: apt-get install {APT_PACKAGES} (or run 'make system-deps')")


def build(directory):
    """Path of the compiled reader in ``directory`` (compiled here), or a skip."""
    cxx = shutil.which(os.environ.get("CXX", "g++")) or shutil.which("c++")
    if cxx is None:
        _skip("no C++ compiler (g++) to build the PCL typed reader")
    pkg = shutil.which("pkg-config")
    if pkg is None:
        _skip("pkg-config is missing, needed to find PCL's headers")
    flags = subprocess.run([pkg, "--cflags", "pcl_io"], capture_output=True, text=True, check=False)
    if flags.returncode != 0:
        _skip("PCL's development files (pcl_io.pc) are missing")
    include = [f[2:] for f in flags.stdout.split() if f.startswith("-I")]
    if not any((pathlib.Path(d) / "pcl" / "io" / "pcd_io.h").is_file() for d in include):
        _skip("PCL's header pcl/io/pcd_io.h is missing")
    exe = pathlib.Path(directory) / "pcl_typed_reader"
    cmd = [cxx, "-std=c++17", "-O1", *flags.stdout.split(), str(SOURCE), "-o", str(exe),
           "-lpcl_io", "-lpcl_common"]
    run = subprocess.run(cmd, capture_output=True, text=True, timeout=600, check=False)
    assert run.returncode == 0, f"{' '.join(cmd)}\n{run.stderr[-4000:]}"
    return exe


def read(exe, point_type, path):
    """Rows (N, F) float64 of what PCL read into the driver's struct, fields in the
    struct's order. Fails when PCL could not map a field onto the struct (its name, type
    or count differ) or could not load the file."""
    run = subprocess.run([str(exe), point_type, str(path)], capture_output=True, text=True,
                         timeout=120, check=False)
    log = run.stdout[-2000:] + run.stderr[-2000:]
    assert run.returncode == 0, log
    assert "Failed to find match" not in run.stderr, run.stderr
    lines = run.stdout.splitlines()
    assert lines and lines[0].startswith("points "), log
    n = int(lines[0].split()[1])
    rows = [line.split()[1:] for line in lines[1:] if line.startswith("p")]
    assert len(rows) == n, log
    # exact: floats and doubles printed with 17 significant digits, integers as integers
    return np.array(rows, dtype=np.float64).reshape(n, -1) if n else np.zeros((0, 0))

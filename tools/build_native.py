"""Compile RLS's optional native helper (a C loop over Embree packets), for this
machine in place, or for the platforms the extension zips are built for.

    python tools/build_native.py                      this machine, in place (gcc/cc)
    python tools/build_native.py --platforms all      every zip platform, into build/native
    python tools/build_native.py --platforms linux-x64,windows-x64

In place: ``rls_addon/core/native/c/_rls_native.so`` (``.dylib`` on macOS,
``.dll`` on Windows), what the tests and ``python -m rls_addon`` use here. Needs a C
compiler (gcc/cc); without one, or on failure, it says so and exits 0: the extension
then casts Embree packets from Python (slower with several threads).

For the zips: ``build/native/<platform>/`` (Blender's platform names), cross-compiled
from this Linux machine with Zig's C compiler (``python -m ziglang cc``, the ``ziglang``
wheel pinned in requirements-build.txt): Linux against glibc 2.28 (Blender's own
minimum), Windows through MinGW-w64 (KERNEL32 and the Universal CRT only), macOS 11.0
and later. Without Zig, this machine's own compiler builds its own platform's zip; on
Linux the sources bind the pthread calls to their first glibc version
(``rls_threads.h``: glibc 2.34 gave them a new one) and the build is checked to need
nothing newer than glibc 2.28 (``GLIBC_MAX``), else the zip goes without a loop. A
platform that cannot be built is reported, never fatal: its zip then has no compiled
loop and Embree runs from Python there. A build is redone only when the sources or the
command change (``build.json`` beside each build records both).

Every build uses ``-ffp-contract=off`` (no fused multiply-add on any target, so float64
refinement gives the same bits everywhere) and ``-fvisibility=hidden`` (only the
``RLS_EXPORT`` entry points are exported).
"""

import argparse
import hashlib
import json
import os
import platform as _platform
import shutil
import struct
import subprocess
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
NATIVE = ROOT / "rls_addon" / "core" / "native" / "c"
# One library: the Embree loop, the per-hit stage of a frame (points.c), the
# footprint's depth-edge test and its probe sectors (edges.c) and probe sub-rays
# (probes.c), the weather's false returns (weather.c), a study candidate's disk counts
# (disks.c), the ghost bounces' set-up and landing (ghosts.c), a static cast's returns
# (returns.c), a footprint's echoes (echoes.c), the ground-truth boxes' counts
# (boxes.c), a moving sensor's ray origins (tracks.c) and the instances of a sweep's
# moving objects attached to their Embree scene (instances.c).
SOURCES = [NATIVE / "embree_loop.c", NATIVE / "points.c", NATIVE / "edges.c",
           NATIVE / "weather.c", NATIVE / "probes.c", NATIVE / "disks.c",
           NATIVE / "ghosts.c", NATIVE / "returns.c", NATIVE / "echoes.c",
           NATIVE / "boxes.c", NATIVE / "tracks.c", NATIVE / "instances.c"]
HEADERS = [NATIVE / "rls_threads.h", NATIVE / "rls_shares.h", NATIVE / "rls_sectors.h"]
BUILD = ROOT / "build" / "native"
# The newest glibc a Linux loop may need: Blender 4.2's (its minimum, and the Zig target's).
GLIBC_MAX = (2, 28)
ZIG_CACHE = ROOT / "build" / "zig-cache"

# Blender platform -> (Zig target, sys.platform of that system: names the file).
TARGETS = {
    "linux-x64": ("x86_64-linux-gnu.2.28", "linux"),
    "windows-x64": ("x86_64-windows-gnu", "win32"),
    "macos-arm64": ("aarch64-macos.11.0", "darwin"),
    "macos-x64": ("x86_64-macos.11.0", "darwin"),
}
FLAGS = ["-O2", "-shared", "-fPIC", "-fvisibility=hidden", "-ffp-contract=off",
         "-Wall", "-Werror=implicit-function-declaration"]
# The library's entry points: every platform's build exports these and nothing else
# (tests/blender/test_platform_zips.py reads each zip's binary).
EXPORTS = ("rls_embree_launch", "rls_embree_finish", "rls_embree_abi",
           "rls_points_assemble", "rls_points_abi",
           "rls_depth_edges", "rls_edge_sectors", "rls_edges_abi",
           "rls_false_returns", "rls_weather_abi",
           "rls_probe_sectors", "rls_ring_rays", "rls_probes_abi",
           "rls_disk_counts", "rls_disks_abi",
           "rls_ghost_aim", "rls_ghost_land", "rls_ghosts_abi",
           "rls_static_returns", "rls_returns_abi",
           "rls_echo_group", "rls_echo_choose", "rls_echoes_abi",
           "rls_box_counts", "rls_boxes_abi", "rls_own_points", "rls_own_points_abi",
           "rls_track_positions", "rls_tracks_abi",
           "rls_attach_instances", "rls_instances_abi")


def _cstr(data, off):
    return data[off:data.index(b"\0", off)].decode()


def read_elf(data):
    """(architecture, type, exported functions, versions needed) of a 64-bit
    little-endian ELF file's bytes; AssertionError for anything else."""
    assert data[:4] == b"\x7fELF", "not ELF"
    assert data[4] == 2 and data[5] == 1, "not 64-bit little-endian"
    e_type, e_machine = struct.unpack_from("<HH", data, 16)
    shoff, = struct.unpack_from("<Q", data, 0x28)
    shentsize, shnum = struct.unpack_from("<HH", data, 0x3A)
    sections = [struct.unpack_from("<IIQQQQIIQQ", data, shoff + i * shentsize)
                for i in range(shnum)]
    exports, needed = set(), set()
    for sh in sections:
        _, sh_type, _, _, off, size, link, info, _, entsize = sh
        if sh_type == 11:  # SHT_DYNSYM
            strtab = sections[link][4]
            for i in range(size // entsize):
                name, st_info, st_other, shndx, _, _ = struct.unpack_from("<IBBHQQ", data,
                                                                          off + i * entsize)
                if shndx != 0 and st_info >> 4 == 1 and st_info & 0xF == 2 and st_other & 3 == 0:
                    exports.add(_cstr(data, strtab + name))
        if sh_type == 0x6FFFFFFE:  # SHT_GNU_verneed
            strtab = sections[link][4]
            at = off
            for _ in range(info):
                _, cnt, _, aux, nxt = struct.unpack_from("<HHIII", data, at)
                a = at + aux
                for _ in range(cnt):
                    _, _, _, vname, anext = struct.unpack_from("<IHHII", data, a)
                    needed.add(_cstr(data, strtab + vname))
                    a += anext
                at += nxt
    arch = {62: "x86-64", 183: "arm64"}.get(e_machine, str(e_machine))
    return arch, {3: "shared object"}.get(e_type, str(e_type)), exports, needed


def glibc_needed(data):
    """The newest glibc version (a tuple) an ELF library's bytes need, or None."""
    versions = [tuple(int(x) for x in v[6:].split(".")) for v in read_elf(data)[3]
                if v.startswith("GLIBC_") and v[6:].replace(".", "").isdigit()]
    return max(versions) if versions else None


def library_name(sys_platform):
    """The loop's file name on ``sys_platform`` (the loader's own rule)."""
    sys.path.insert(0, str(ROOT))
    try:
        from rls_addon.core.native.library import library_name
    finally:
        sys.path.remove(str(ROOT))
    return library_name(sys_platform)


def host_platform():
    """This machine as a Blender platform name (e.g. linux-x64), as blender_ext.py names it."""
    system = {"darwin": "macos"}.get(sys.platform, "windows" if sys.platform == "win32"
                                     else _platform.system().lower())
    machine = _platform.machine().lower()
    machine = {"x86_64": "x64", "amd64": "x64", "aarch64": "arm64"}.get(machine, machine)
    return f"{system}-{machine}"


def _sources_digest():
    h = hashlib.sha256()
    for path in [*SOURCES, *HEADERS]:
        h.update(path.name.encode() + b"\0" + path.read_bytes())
    return h.hexdigest()


def _loads(path):
    """True when the loader would use the build at ``path`` (not stale, e.g. a build
    newer than a checkout's sources but older than their interface)."""
    sys.path.insert(0, str(ROOT))
    try:
        from rls_addon.core.casting.embree_loop import load_native

        load_native(str(path))
        return True
    except OSError:
        return False
    finally:
        sys.path.remove(str(ROOT))


def build_host():
    """Compile the loop for this machine into the package (gcc or cc). Returns a line
    saying what happened; never raises on a compiler's failure."""
    out = NATIVE / library_name(sys.platform)
    cc = shutil.which("gcc") or shutil.which("cc")
    if cc is None:
        return "build_native: no C compiler found; the Python packet loop will be used"
    newest = max(p.stat().st_mtime for p in [*SOURCES, *HEADERS])
    if out.exists() and out.stat().st_mtime >= newest and _loads(out):
        return ""
    cmd = [cc, *FLAGS, "-pthread", "-o", str(out), *map(str, SOURCES), "-lm",
           *_pthread_library(cc)]
    proc = subprocess.run(cmd, capture_output=True, text=True)
    if proc.returncode != 0:
        return ("build_native: compiling failed; the Python packet loop will be used\n"
                + proc.stderr)
    return f"build_native: {out.relative_to(ROOT)}"


def _pthread_library(cc):
    """On glibc, libpthread.so.0 named as needed: before glibc 2.34 the pthread calls the
    sources bind to their first version live there, not in libc (as Zig's 2.28 build
    names it); since, it is an empty library kept for this."""
    if not sys.platform.startswith("linux"):
        return []
    found = subprocess.run([cc, "-print-file-name=libpthread.so.0"], capture_output=True,
                           text=True).stdout.strip()
    return ["-Wl,--no-as-needed", "-l:libpthread.so.0", "-Wl,--as-needed"] \
        if os.path.isabs(found) else []


def zig_command():
    """The Zig C compiler from the ``ziglang`` wheel, or None (with the reason)."""
    try:
        proc = subprocess.run([sys.executable, "-m", "ziglang", "version"],
                              capture_output=True, text=True, timeout=120)
    except (OSError, subprocess.TimeoutExpired) as exc:
        return None, f"Zig could not run ({exc})"
    if proc.returncode != 0:
        return None, ("the ziglang wheel is not installed (pip install -r "
                      "requirements-build.txt; make build does)")
    return [sys.executable, "-m", "ziglang", "cc"], proc.stdout.strip()


def build_platform(name, zig=None, out_root=BUILD):
    """Cross-compile the loop for Blender platform ``name`` into ``out_root/name``.

    Returns (path or None, note): the library, or None and why it was not built."""
    if name not in TARGETS:
        return None, f"no target known for platform {name!r}"
    target, sys_platform = TARGETS[name]
    if zig is None:
        zig = zig_command()
    cc, version = zig
    out_dir = out_root / name
    out = out_dir / library_name(sys_platform)
    if cc is None:
        if name != host_platform():
            return None, version
        # This machine's own compiler still serves its own platform's zip, built
        # against this machine's C library (which may be newer than users' systems).
        msg = build_host()
        host = NATIVE / library_name(sys.platform)
        if not host.exists() or "failed" in msg:
            return None, f"{version}; {msg or 'no host build'}"
        if name.startswith("linux-"):
            newest = glibc_needed(host.read_bytes())
            if newest is not None and newest > GLIBC_MAX:
                return None, (f"{version}; this machine's C compiler made a loop that needs "
                              f"glibc {'.'.join(map(str, newest))}, newer than Blender's "
                              f"{'.'.join(map(str, GLIBC_MAX))}")
        out_dir.mkdir(parents=True, exist_ok=True)
        (out_dir / "build.json").unlink(missing_ok=True)
        shutil.copy2(host, out)
        return out, f"{version}: built with this machine's C compiler instead"
    cmd = [*cc, "-target", target, *FLAGS, "-s", "-o", out.name, *map(str, SOURCES)]
    record = {"command": cmd[2:], "zig": version, "sources": _sources_digest()}
    stamp = out_dir / "build.json"
    if out.exists() and stamp.exists():
        try:
            if json.loads(stamp.read_text()) == record:
                return out, "up to date"
        except ValueError:
            pass
    out_dir.mkdir(parents=True, exist_ok=True)
    env = dict(os.environ, ZIG_GLOBAL_CACHE_DIR=str(ZIG_CACHE),
               ZIG_LOCAL_CACHE_DIR=str(ZIG_CACHE))
    # In a scratch directory: the Windows link also writes an import library and a
    # PDB next to its output, which the zip must not carry.
    with tempfile.TemporaryDirectory(prefix=f"rls-native-{name}-") as tmp:
        try:
            proc = subprocess.run(cmd, cwd=tmp, env=env, capture_output=True, text=True,
                                  timeout=900)
        except subprocess.TimeoutExpired:
            return None, f"zig cc -target {target} did not finish in 15 minutes"
        built = Path(tmp) / out.name
        if proc.returncode != 0 or not built.exists():
            err = (proc.stderr or proc.stdout).strip().splitlines()
            return None, f"zig cc -target {target} failed: " + " | ".join(err[-6:])
        shutil.copy2(built, out)
    stamp.write_text(json.dumps(record, indent=1) + "\n")
    return out, f"built with zig cc -target {target}"


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--platforms", default="",
                    help="comma-separated Blender platforms (or 'all') to cross-compile "
                         "into build/native; default: this machine, in place")
    args = ap.parse_args(argv)
    if not args.platforms:
        msg = build_host()
        if msg:
            print(msg, file=sys.stderr if "failed" in msg else sys.stdout)
        return 0
    names = list(TARGETS) if args.platforms == "all" else args.platforms.split(",")
    zig = zig_command()
    for name in names:
        path, note = build_platform(name.strip(), zig)
        where = path.relative_to(ROOT) if path else "not built"
        print(f"build_native: {name}: {where} ({note})")
    return 0


if __name__ == "__main__":
    sys.exit(main())

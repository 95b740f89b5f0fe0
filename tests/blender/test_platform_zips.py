"""The zips ``make build`` writes, one per platform: Blender's validator accepts each,
each holds exactly its platform's wheels and its platform's compiled loop, and that
loop is a library of the right format and architecture exporting what the loader
calls (headers and export tables read here, in Python: ELF, PE32+, Mach-O).

The Linux x64 zip is also installed into Blender and scanned with
(tests/blender/test_installed_extension.py); here its loop is loaded next to the
in-tree build and must cast the same bits.
"""

import re
import struct
import subprocess
import sys
import tomllib
import zipfile
from pathlib import Path

import numpy as np
import pytest

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT / "tools"))
import build_extension  # noqa: E402
import build_native  # noqa: E402

from rls_addon.core.casting import embree, embree_loop
from rls_addon.core.native.library import library_name
from tests.core.external_tools import missing

MANIFEST = tomllib.loads((ROOT / "blender_manifest.toml").read_text())
ENTRY_POINTS = set(build_native.EXPORTS)  # what every platform's library exports
LINKER_SYMBOLS = {"_init", "_fini", "_mh_dylib_header", "__dso_handle"}
# Blender platform -> (format, architecture, sys.platform naming the file)
EXPECTED = {
    "linux-x64": ("elf", "x86-64", "linux"),
    "windows-x64": ("pe", "x86-64", "win32"),
    "macos-arm64": ("macho", "arm64", "darwin"),
    "macos-x64": ("macho", "x86-64", "darwin"),
}


def zip_path(platform):
    path = ROOT / "dist" / build_extension.zip_name(MANIFEST, platform)
    if not path.exists():  # make test-blender builds only the Linux zip it installs
        missing(f"{path.name} is missing: run 'make build' (make test does)")
    return path


def test_every_manifest_platform_has_a_zip_and_a_target():
    assert MANIFEST["platforms"] == list(build_extension.PLATFORMS) == list(EXPECTED)
    assert set(build_native.TARGETS) == set(EXPECTED)
    for platform in EXPECTED:
        assert zip_path(platform).name == (f"rls_addon-{MANIFEST['version']}-"
                                           f"{platform.replace('-', '_')}.zip")
    # No zip of an older build layout that users could pick by mistake.
    assert not (ROOT / "dist" / f"rls_addon-{MANIFEST['version']}.zip").exists()


@pytest.mark.parametrize("platform", list(EXPECTED))
def test_blender_validates_the_zip_and_it_declares_its_platform(platform):
    path = zip_path(platform)
    tool = build_extension.blender_ext_path()
    proc = subprocess.run([sys.executable, str(tool), "validate", str(path)],
                          capture_output=True, text=True, timeout=120)
    assert proc.returncode == 0, proc.stdout + proc.stderr
    with zipfile.ZipFile(path) as z:
        manifest = tomllib.loads(z.read("blender_manifest.toml").decode())
        assert z.testzip() is None
    assert manifest["platforms"] == [platform]
    assert manifest["build"]["generated"]["platforms"] == [platform]
    assert manifest["id"] == MANIFEST["id"] and manifest["version"] == MANIFEST["version"]


def _wheels(z):
    return sorted(n for n in z.namelist() if n.startswith("wheels/"))


@pytest.mark.parametrize("platform", list(EXPECTED))
def test_zip_holds_exactly_the_wheels_of_its_platform(platform):
    with zipfile.ZipFile(zip_path(platform)) as z:
        wheels = _wheels(z)
        manifest = tomllib.loads(z.read("blender_manifest.toml").decode())
    names = [w.split("/", 1)[1] for w in wheels]
    assert all(n.endswith(".whl") for n in names), names
    want = {(re.sub(r"[-_.]+", "_", req.partition("==")[0]).lower(), req.partition("==")[2])
            for req, _ in build_extension.PLATFORMS[platform]}
    got = {tuple(n.split("-")[:2]) for n in names}
    got = {(re.sub(r"[-_.]+", "_", a).lower(), b) for a, b in got}
    assert got == want and len(names) == len(want), names
    for n in names:  # Blender's own rule: installable on this platform
        assert build_extension.wheel_for_platform(n, platform), n
        others = [p for p in EXPECTED if p != platform and build_extension.wheel_for_platform(n, p)]
        if not n.endswith("-none-any.whl"):
            assert others == [], f"{n} also fits {others}"
    listed = sorted(manifest["wheels"])
    assert listed == sorted(f"./{w}" for w in wheels)
    assert sorted(manifest["build"]["generated"]["wheels"]) == listed


# ---- reading the compiled files' headers ------------------------------------------

read_elf = build_native.read_elf  # (architecture, type, exports, versions needed)
_cstr = build_native._cstr


def read_pe(data):
    """(architecture, kind, exported names, imported DLLs)."""
    assert data[:2] == b"MZ", "not a PE file"
    pe, = struct.unpack_from("<I", data, 0x3C)
    assert data[pe:pe + 4] == b"PE\0\0"
    machine, nsect, _, _, _, optsize, chars = struct.unpack_from("<HHIIIHH", data, pe + 4)
    opt = pe + 24
    magic, = struct.unpack_from("<H", data, opt)
    assert magic == 0x20B, "not PE32+"
    ndirs, = struct.unpack_from("<I", data, opt + 108)
    dirs = [struct.unpack_from("<II", data, opt + 112 + 8 * i) for i in range(ndirs)]
    sects = [struct.unpack_from("<8sIIII", data, opt + optsize + 40 * i) for i in range(nsect)]

    def off(rva):
        for _, vsize, va, rawsize, raw in sects:
            if va <= rva < va + max(vsize, rawsize):
                return rva - va + raw
        raise ValueError(f"RVA {rva:#x} in no section")

    exports = set()
    rva, size = dirs[0]
    if size:
        # IMAGE_EXPORT_DIRECTORY: NumberOfNames at 24, AddressOfNames at 32
        n_names, = struct.unpack_from("<I", data, off(rva) + 24)
        names_rva, = struct.unpack_from("<I", data, off(rva) + 32)
        for i in range(n_names):
            name_rva, = struct.unpack_from("<I", data, off(names_rva) + 4 * i)
            exports.add(_cstr(data, off(name_rva)))
    imports = []
    rva, size = dirs[1]
    at = off(rva) if size else None
    while at is not None:
        desc = struct.unpack_from("<IIIII", data, at)
        if not any(desc):
            break
        imports.append(_cstr(data, off(desc[3])))
        at += 20
    arch = {0x8664: "x86-64", 0xAA64: "arm64"}.get(machine, hex(machine))
    return arch, "DLL" if chars & 0x2000 else "EXE", exports, imports


def _uleb(data, at):
    value = shift = 0
    while True:
        b = data[at]
        at += 1
        value |= (b & 0x7F) << shift
        shift += 7
        if b < 0x80:
            return value, at


def _trie(data, start, at, prefix, out):
    size, p = _uleb(data, at)
    if size:
        out.add(prefix)
    p += size
    count = data[p]
    p += 1
    for _ in range(count):
        end = data.index(b"\0", p)
        edge = data[p:end].decode()
        child, p = _uleb(data, end + 1)
        _trie(data, start, start + child, prefix + edge, out)


def read_macho(data):
    """(architecture, kind, exported names (without the leading _), linked dylibs,
    minimum macOS version)."""
    magic, cputype, _, filetype, ncmds, _ = struct.unpack_from("<IiIIII", data, 0)
    assert magic == 0xFEEDFACF, "not a 64-bit little-endian Mach-O"
    at, exports, dylibs, minos = 32, set(), [], None
    symtab = trie = None
    for _ in range(ncmds):
        cmd, size = struct.unpack_from("<II", data, at)
        if cmd == 0x2:  # LC_SYMTAB
            symtab = struct.unpack_from("<IIII", data, at + 8)
        elif cmd == 0x80000033:  # LC_DYLD_EXPORTS_TRIE
            trie = struct.unpack_from("<II", data, at + 8)
        elif cmd == 0x80000022:  # LC_DYLD_INFO_ONLY: export_off, export_size
            trie = struct.unpack_from("<II", data, at + 40)
        elif cmd == 0xC:  # LC_LOAD_DYLIB
            name, = struct.unpack_from("<I", data, at + 8)
            dylibs.append(_cstr(data, at + name))
        elif cmd == 0x32:  # LC_BUILD_VERSION
            _, v = struct.unpack_from("<II", data, at + 8)
            minos = (v >> 16, (v >> 8) & 0xFF, v & 0xFF)
        at += size
    if trie and trie[1]:
        _trie(data, trie[0], trie[0], "", exports)
    elif symtab:
        symoff, nsyms, stroff, _ = symtab
        for i in range(nsyms):
            strx, ntype, _, _, _ = struct.unpack_from("<IBBHQ", data, symoff + 16 * i)
            if ntype & 0xE0 == 0 and ntype & 0x01 and ntype & 0x0E == 0x0E:
                exports.add(_cstr(data, stroff + strx))
    exports = {e[1:] if e.startswith("_") else e for e in exports}
    arch = {0x0100000C: "arm64", 0x01000007: "x86-64"}.get(cputype, hex(cputype))
    return arch, {6: "dylib"}.get(filetype, str(filetype)), exports, dylibs, minos


def _binaries(z):
    """Entries outside wheels/ that are compiled code (by magic number or suffix)."""
    out = {}
    for n in z.namelist():
        if n.startswith("wheels/") or n.endswith("/"):
            continue
        head = z.read(n)[:4]
        if (head[:4] == b"\x7fELF" or head[:2] == b"MZ" or head[:4] == b"\xcf\xfa\xed\xfe"
                or n.endswith((".so", ".dll", ".dylib", ".pyd"))):
            out[n] = z.read(n)
    return out


@pytest.mark.parametrize("platform", list(EXPECTED))
def test_zip_holds_its_compiled_loop_only_of_the_right_format(platform):
    fmt, arch, sys_platform = EXPECTED[platform]
    with zipfile.ZipFile(zip_path(platform)) as z:
        binaries = _binaries(z)
    name = "core/native/c/" + library_name(sys_platform)
    assert list(binaries) == [name], f"{platform}: compiled files {sorted(binaries)}"
    data = binaries[name]
    if fmt == "elf":
        got_arch, kind, exports, glibc = read_elf(data)
        assert (got_arch, kind) == (arch, "shared object")
        # Blender 4.2+ runs on glibc 2.28: the loop must not need anything newer.
        assert build_native.GLIBC_MAX == (2, 28)
        versions = [tuple(int(x) for x in v[6:].split(".")) for v in glibc
                    if v.startswith("GLIBC_")]
        assert versions and max(versions) <= (2, 28), sorted(glibc)
    elif fmt == "pe":
        got_arch, kind, exports, imports = read_pe(data)
        assert (got_arch, kind) == (arch, "DLL")
        system = [d for d in imports
                  if d.lower() == "kernel32.dll" or d.lower().startswith("api-ms-win-crt-")]
        assert imports and system == imports, imports  # nothing to ship beside it
    else:
        got_arch, kind, exports, dylibs, minos = read_macho(data)
        assert (got_arch, kind) == (arch, "dylib")
        assert dylibs == ["/usr/lib/libSystem.B.dylib"], dylibs
        assert minos is not None and minos <= (11, 2, 0), minos  # Blender's minimum macOS
    assert ENTRY_POINTS <= exports, sorted(exports)
    # Nothing else but what the linker itself defines (ELF _init/_fini, Mach-O headers).
    assert exports <= ENTRY_POINTS | LINKER_SYMBOLS, sorted(exports)


def test_a_linux_loop_built_without_zig_needs_no_newer_glibc(tmp_path, monkeypatch):
    """make build-linux on a machine without the ziglang wheel builds the Linux zip's
    loop with this machine's compiler: it too must load on Blender's glibc 2.28 (with
    gcc on glibc 2.34+ it needed GLIBC_2.34 for pthread_create and pthread_join); a
    build that still needs a newer glibc is left out of the zip, saying why."""
    import shutil

    if build_native.host_platform() != "linux-x64" or shutil.which("gcc") is None:
        missing("building the Linux loop without Zig needs gcc on Linux x64")
    lib, note = build_native.build_platform("linux-x64", zig=(None, "no Zig here"),
                                            out_root=tmp_path)
    assert lib is not None, note
    assert "this machine's C compiler" in note
    newest = build_native.glibc_needed(lib.read_bytes())
    assert newest is not None and newest <= build_native.GLIBC_MAX == (2, 28), newest
    embree_loop.load_native(str(lib))  # and it is a loop the loader takes
    monkeypatch.setattr(build_native, "glibc_needed", lambda data: (2, 34))
    lib, note = build_native.build_platform("linux-x64", zig=(None, "no Zig here"),
                                            out_root=tmp_path / "again")
    assert lib is None and "needs glibc 2.34, newer than Blender's 2.28" in note


def test_header_readers_reject_other_formats():
    """The readers above are not a rubber stamp: each one refuses the others' files."""
    zips = {p: _binaries(zipfile.ZipFile(zip_path(p))) for p in EXPECTED}
    so, dll = next(iter(zips["linux-x64"].values())), next(iter(zips["windows-x64"].values()))
    arm = next(iter(zips["macos-arm64"].values()))
    for reader, other in ((read_elf, dll), (read_pe, arm), (read_macho, so)):
        with pytest.raises(AssertionError):
            reader(other)
    assert read_macho(next(iter(zips["macos-x64"].values())))[0] == "x86-64"
    assert read_macho(arm)[0] == "arm64"


def test_linux_zip_loop_casts_the_same_bits_as_the_in_tree_loop(tmp_path, monkeypatch):
    """The shipped Linux loop (Zig, glibc 2.28) and the in-tree one the other tests
    use (gcc) refine every hit to the same float64 bits."""
    if not embree.available() or embree._native_loop() is None:
        pytest.fail("embreex and the in-tree compiled loop are needed (make test builds them)")
    from rls_addon.core.casting import triangle_planes

    name = "core/native/c/" + library_name("linux")
    with zipfile.ZipFile(zip_path("linux-x64")) as z:
        (tmp_path / "zip.so").write_bytes(z.read(name))
    shipped = embree_loop.load_native(str(tmp_path / "zip.so"))
    rng = np.random.default_rng(11)
    c = rng.uniform(-30, 30, (20000, 3))
    v = (c[:, None] + rng.normal(0, 1.0, (20000, 3, 3))).reshape(-1, 3)
    t = np.arange(len(v)).reshape(-1, 3)
    d = rng.normal(size=(50000, 3))
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    o = rng.uniform(-2, 2, (50000, 3))
    caster = embree.EmbreeCaster(v, t, threads=2)
    planes = triangle_planes(v, t)
    here = caster.cast_refined(o, d, 40.0, planes)
    monkeypatch.setattr(embree_loop, "_NATIVE", shipped)
    there = caster.cast_refined(o, d, 40.0, planes)
    assert (here[1] >= 0).any() and (here[1] < 0).any()
    for a, b in zip(here, there):
        assert a.dtype == b.dtype and np.array_equal(a, b)


def _compile(tmp_path, name, body):
    cc = build_native.shutil.which("gcc") or build_native.shutil.which("cc")
    if cc is None:
        pytest.fail("gcc is needed (make test's machine has it)")
    src = tmp_path / f"{name}.c"
    src.write_text(body)
    out = tmp_path / f"{name}.so"
    subprocess.run([cc, "-shared", "-fPIC", "-o", str(out), str(src)], check=True)
    return str(out)


def test_loader_refuses_stale_builds(tmp_path):
    old = "void *rls_embree_launch(void) { return 0; }\nvoid rls_embree_finish(void *b) {}\n"
    no_abi = _compile(tmp_path, "no_abi", old)
    with pytest.raises(OSError, match="stale build"):
        embree_loop.load_native(no_abi)
    other = _compile(tmp_path, "abi1", old + "int rls_embree_abi(void) { return 1; }\n")
    with pytest.raises(OSError, match=f"interface 1, this RLS needs {embree_loop.NATIVE_ABI}"):
        embree_loop.load_native(other)
    ok = _compile(tmp_path, "abi_ok", old + "int rls_embree_abi(void) { return %d; }\n"
                  % embree_loop.NATIVE_ABI)
    start, finish = embree_loop.load_native(ok)
    assert start.argtypes and finish.argtypes
    assert library_name("win32") == "_rls_native.dll"
    assert library_name("darwin") == "_rls_native.dylib"
    assert library_name("linux") == "_rls_native.so"


def test_a_target_that_fails_is_reported_and_its_zip_still_built(tmp_path, monkeypatch, capsys):
    path, note = build_native.build_platform("windows-x64", zig=(["false"], "test"),
                                             out_root=tmp_path / "native")
    assert path is None and "failed" in note
    path, note = build_native.build_platform("windows-x64", zig=(None, "no zig here"),
                                             out_root=tmp_path / "native")
    assert path is None and note == "no zig here"
    monkeypatch.setattr(build_native, "build_platform",
                        lambda name, zig=None, out_root=None: (None, "simulated failure"))
    assert build_extension.main(["--out", str(tmp_path / "dist"),
                                 "--platforms", "windows-x64"]) == 0
    err = capsys.readouterr()
    assert "windows-x64: the compiled loop could not be built (simulated failure)" in err.err
    built = tmp_path / "dist" / build_extension.zip_name(MANIFEST, "windows-x64")
    with zipfile.ZipFile(built) as z:
        assert _binaries(z) == {}
        assert len(_wheels(z)) == 1  # Embree is still bundled: packets from Python
    assert "no compiled loop (simulated failure)" in err.out


def test_staged_manifest_declares_one_platform():
    text = (ROOT / "blender_manifest.toml").read_text()
    staged = tomllib.loads(build_extension.staged_manifest(text, "macos-x64", ["a-1-py3-none-any.whl"]))
    assert staged["platforms"] == ["macos-x64"]
    assert staged["wheels"] == ["./wheels/a-1-py3-none-any.whl"]
    src = tomllib.loads(text)
    assert {k: v for k, v in staged.items() if k not in ("platforms", "wheels")} == \
        {k: v for k, v in src.items() if k != "platforms"}



@pytest.mark.parametrize("platform", ["macos-arm64", "macos-x64"])
def test_macos_wheels_are_all_the_backend_needs(platform, tmp_path):
    """Blender installs a zip's wheels without their dependencies: with nothing but the
    standard library, numpy (Blender's) and this venv's pyemblite (the same version as
    the zip's, for Linux: the same Python modules), the macOS backend imports and
    casts through the caster the zip's RLS picks."""
    import importlib.util

    with zipfile.ZipFile(zip_path(platform)) as z:
        names = [Path(n).name for n in _wheels(z)]
    assert len(names) == 1 and names[0].startswith("pyemblite-"), names
    import pyemblite

    assert pyemblite.__version__ == names[0].split("-")[1], "the venv's pyemblite differs"
    site = tmp_path / "site"
    site.mkdir()
    for mod in ("numpy", "pyemblite"):
        pkg = Path(importlib.util.find_spec(mod).origin).parent
        (site / mod).symlink_to(pkg)
        libs = pkg.parent / f"{mod}.libs"
        if libs.exists():
            (site / libs.name).symlink_to(libs)
    script = (
        "import sys\n"
        "sys.path = [p for p in sys.path if 'site-packages' not in p and 'dist-packages' not in p]\n"
        f"sys.path += [{str(site)!r}, {str(ROOT)!r}]\n"
        "import builtins\n"
        "real = builtins.__import__\n"
        "def no_embreex(name, *a, **k):\n"
        "    if name.split('.')[0] in ('embreex', 'open3d'):\n"
        "        raise ImportError('not in the macOS zip')\n"
        "    return real(name, *a, **k)\n"
        "builtins.__import__ = no_embreex\n"
        "from rls_addon.core import casting\n"
        "factory, notice = casting.caster_factory('auto')\n"
        "assert factory is casting.EmbliteCaster and notice is None, (factory, notice)\n"
        "import numpy as np\n"
        "c = factory(np.array([[-1.0, -1, 0], [3, -1, 0], [-1, 3, 0]]), np.array([[0, 1, 2]]))\n"
        "d, t = c.cast(np.array([[0.0, 0, 2]]), np.array([[0.0, 0, -1], [0, 0, 1]]), 10.0)\n"
        "assert abs(d[0] - 2) < 1e-6 and list(t) == [0, -1], (d, t)\n"
        "print(casting.backend_status('auto')[1])\n")
    proc = subprocess.run([sys.executable, "-S", "-c", script], capture_output=True,
                          text=True, timeout=300, cwd=tmp_path)
    assert proc.returncode == 0, proc.stderr[-3000:]
    assert proc.stdout.strip().splitlines()[-1].startswith("Embree 4 from the pyemblite wheel")

"""Build and validate one extension zip per platform with Blender's own tooling.

The repository keeps the manifest and ``presets/`` at the top level and the package
in ``rls_addon/``; an extension zip needs them side by side at its root. For every
platform in ``PLATFORMS`` this stages ``rls_addon/*`` + manifest + presets into
``build/stage/<platform>``, with only that platform's wheels (``wheels/``, listed in
the staged manifest's ``wheels``) and only that platform's build of the compiled
Embree loop (``tools/build_native.py``, cross-compiled with Zig), and runs
``blender_ext.py build --split-platforms`` and ``validate`` (shipped inside the
``bpy`` wheel) on it:

    dist/rls_addon-<version>-linux_x64.zip     Embree 4 (embreex) + the compiled loop
    dist/rls_addon-<version>-windows_x64.zip   Embree 4 (embreex) + the compiled loop
    dist/rls_addon-<version>-macos_arm64.zip   Embree 4 (pyemblite, one core)
    dist/rls_addon-<version>-macos_x64.zip     Embree 4 (pyemblite, one core)

Blender's ``--split-platforms`` filters wheels by platform but copies every other
file into every zip, which is why each platform gets a stage of its own whose manifest
declares that one platform (Blender's tool names the zip after it and records it in
the zip's ``[build.generated]`` table). The source manifest's ``platforms`` lists all
of them. docs/platforms.md explains the choices, with measurements.

Wheels are unmodified PyPI wheels (Blender's rule): ``pip download`` fetches them
into ``build/wheels`` (reused when already there). A platform whose compiled loop
cannot be built still gets its zip (Embree then runs from Python there) and the build
says so; a wheel that cannot be downloaded stops the build (use ``--no-wheels`` for
zips without bundled backends: BVHTree everywhere).

    python tools/build_extension.py [--out dist] [--no-wheels] [--platforms a,b]
"""

import argparse
import functools
import importlib.util
import re
import shutil
import subprocess
import sys
import tomllib
import zipfile
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(Path(__file__).resolve().parent))
import build_native  # noqa: E402  (tools/build_native.py)

PYTHON_VERSION = "3.11"  # Blender 4.2 .. 5.0 embed CPython 3.11

# Blender platform -> the wheels its zip bundles: (requirement, pip --platform tag).
# Each needs only numpy, which Blender ships.
PLATFORMS = {
    "linux-x64": [("embreex==4.4.0.post1", "manylinux_2_28_x86_64")],
    "windows-x64": [("embreex==4.4.0.post1", "win_amd64")],
    # PyPI has no embreex 4 wheel for macOS; pyemblite links Embree 4 statically
    # (single rays, one core): docs/platforms.md weighs it against Open3D and Warp.
    "macos-arm64": [("pyemblite==0.2.9", "macosx_11_0_arm64")],
    "macos-x64": [("pyemblite==0.2.9", "macosx_10_9_x86_64")],
}
# The compiled loop drives the packets of embreex's Embree 4 library; every zip gets
# its build (on macOS it waits unused for an embreex wheel: pyemblite exports no
# library to drive).
NATIVE_PLATFORMS = tuple(build_native.TARGETS)


def blender_ext_path():
    spec = importlib.util.find_spec("bpy")  # the wheel's package, without importing it
    if spec is None or spec.origin is None:
        sys.exit("build: the bpy module is not installed (run 'make venv')")
    base = Path(spec.origin).resolve().parent
    found = sorted(base.glob("*/scripts/addons_core/bl_pkg/cli/blender_ext.py"))
    if not found:
        sys.exit(f"build: blender_ext.py not found under {base}")
    return found[-1]


@functools.lru_cache(maxsize=1)
def blender_ext_module():
    """Blender's extension tool as a module (its wheel-to-platform rules)."""
    path = blender_ext_path()
    spec = importlib.util.spec_from_file_location("_rls_blender_ext", path)
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def wheel_for_platform(wheel_name, platform):
    """True when Blender installs the wheel file ``wheel_name`` on ``platform``."""
    return blender_ext_module().blender_platform_compatible_with_wheel_platform_from_filepath(
        platform, wheel_name)


def _is_loop(name):
    return name.startswith("_rls_native.") and not name.endswith((".c", ".h"))


def stage(dest, platform, native_lib):
    """Copy the package, presets and extras into ``dest``, with the compiled loop of
    ``platform`` only (``native_lib``, or none)."""
    if dest.exists():
        shutil.rmtree(dest)

    def ignore(directory, names):
        skip = {n for n in names if n == "__pycache__" or n.endswith(".pyc")}
        return skip | {n for n in names if _is_loop(n)}  # this machine's own build

    shutil.copytree(ROOT / "rls_addon", dest, ignore=ignore)
    shutil.copytree(ROOT / "presets", dest / "presets", ignore=ignore)
    for extra in ("LICENSE", "README.md"):
        if (ROOT / extra).exists():
            shutil.copy2(ROOT / extra, dest / extra)
    if native_lib is not None:
        shutil.copy2(native_lib, dest / "core" / "native" / "c" / native_lib.name)


def _pip_download(req, tag, dest):
    cmd = [sys.executable, "-m", "pip", "download", "--quiet", "--disable-pip-version-check",
           "--only-binary=:all:", "--no-deps", "--python-version", PYTHON_VERSION,
           "--platform", tag, "-d", str(dest), req]
    return subprocess.run(cmd, capture_output=True, text=True)


def _cached(dest, req, platform):
    name, _, version = req.partition("==")
    stem = re.sub(r"[-_.]+", "_", name).lower()
    return [p for p in sorted(dest.glob("*.whl"))
            if p.name.lower().startswith(f"{stem}-{version}-")
            and wheel_for_platform(p.name, platform)]


def download_wheels(dest, platform):
    """The wheels of ``platform``'s zip, downloaded into ``dest`` when not there yet."""
    dest.mkdir(parents=True, exist_ok=True)
    found = []
    for req, tag in PLATFORMS[platform]:
        have = _cached(dest, req, platform)
        if not have:
            proc = _pip_download(req, tag, dest)
            if proc.returncode != 0:
                sys.exit(f"build: could not download the {req} wheel for {platform} "
                         f"({tag}):\n{proc.stderr.strip()}\n(build without bundled wheels: "
                         "python tools/build_extension.py --no-wheels)")
            have = _cached(dest, req, platform)
        if not have:
            sys.exit(f"build: pip did not leave a {req} wheel for {platform} in {dest}")
        found.append(have[-1])
    return found


def staged_manifest(text, platform, wheel_names):
    """The manifest text declaring ``platform`` alone, with a top-level
    ``wheels = [...]`` (both before the first table)."""
    out = text.splitlines()
    if any(ln.startswith("wheels") for ln in out):
        sys.exit("build: blender_manifest.toml must not list wheels: the build adds them")
    lines = [f'platforms = ["{platform}"]']
    if wheel_names:
        lines += ["wheels = ["] + [f'  "./wheels/{n}",' for n in wheel_names] + ["]"]
    first_table = next((i for i, ln in enumerate(out) if ln.startswith("[")), len(out))
    at = next((i for i, ln in enumerate(out[:first_table]) if ln.startswith("platforms")), None)
    if at is None:
        return "\n".join(out[:first_table] + lines + [""] + out[first_table:]) + "\n"
    end = at  # the source's platforms (every zip's), maybe over several lines
    while "]" not in out[end]:
        end += 1
    return "\n".join(out[:at] + lines + out[end + 1:]) + "\n"


def zip_name(manifest, platform):
    """The file Blender's ``build --split-platforms`` writes for ``platform``."""
    return f"{manifest['id']}-{manifest['version']}-{platform.replace('-', '_')}.zip"


def build_platform(platform, manifest, text, out, tool, wheels_dir, native):
    stage_dir = ROOT / "build" / "stage" / platform
    lib, note = native
    stage(stage_dir, platform, lib)
    wheels = [] if wheels_dir is None else download_wheels(wheels_dir, platform)
    if wheels:
        (stage_dir / "wheels").mkdir()
        for w in wheels:
            shutil.copy2(w, stage_dir / "wheels" / w.name)
    staged = staged_manifest(text, platform, [w.name for w in wheels])
    if tomllib.loads(staged).get("platforms") != [platform]:
        sys.exit(f"build: the staged manifest for {platform} does not declare it alone")
    (stage_dir / "blender_manifest.toml").write_text(staged)
    zip_path = out / zip_name(manifest, platform)
    unsplit = out / f"{manifest['id']}-{manifest['version']}.zip"
    subprocess.run([sys.executable, tool, "build", "--split-platforms",
                    "--source-dir", str(stage_dir), "--output-filepath", str(unsplit)],
                   check=True)
    if not zip_path.exists():
        sys.exit(f"build: blender_ext.py did not write {zip_path}")
    subprocess.run([sys.executable, tool, "validate", str(zip_path)], check=True)
    return zip_path, [w.name for w in wheels], lib, note


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", default=str(ROOT / "dist"))
    ap.add_argument("--no-wheels", action="store_true",
                    help="do not bundle the backends' wheels (embreex, pyemblite): BVHTree")
    ap.add_argument("--platforms", default=",".join(PLATFORMS),
                    help="comma-separated subset of: " + ", ".join(PLATFORMS))
    args = ap.parse_args(argv)
    text = (ROOT / "blender_manifest.toml").read_text()
    manifest = tomllib.loads(text)
    wanted = [p.strip() for p in args.platforms.split(",") if p.strip()]
    unknown = [p for p in wanted if p not in PLATFORMS]
    if unknown:
        sys.exit(f"build: unknown platform(s) {', '.join(unknown)}; choose from "
                 + ", ".join(PLATFORMS))
    declared = manifest.get("platforms", [])
    if sorted(declared) != sorted(PLATFORMS):
        sys.exit("build: blender_manifest.toml's platforms must list the zips built here: "
                 + ", ".join(PLATFORMS))
    out = Path(args.out).resolve()
    out.mkdir(parents=True, exist_ok=True)
    # Older zips of this version for the platforms built now (and the single zip of
    # earlier builds) would be mistaken for this build's: remove them first. The other
    # platforms' zips stay (make test-blender builds only the Linux one).
    for old in [out / zip_name(manifest, p) for p in wanted] + \
            [out / f"{manifest['id']}-{manifest['version']}.zip"]:
        if old.exists():
            old.unlink()
    tool = str(blender_ext_path())
    if (ROOT / "build" / "stage").exists():  # this build's stages only
        shutil.rmtree(ROOT / "build" / "stage")
    zig = build_native.zig_command()
    wheels_dir = None if args.no_wheels else ROOT / "build" / "wheels"
    rows = []
    for platform in wanted:
        native = (build_native.build_platform(platform, zig) if platform in NATIVE_PLATFORMS
                  else (None, "no compiled loop for this platform"))
        if native[0] is None:
            print(f"build: {platform}: the compiled loop could not be built ({native[1]}); "
                  "its zip casts Embree packets from Python", file=sys.stderr)
        rows.append(build_platform(platform, manifest, text, out, tool, wheels_dir, native))
    print("\nbuild: one zip per platform")
    for zip_path, wheels, lib, note in rows:
        size = zip_path.stat().st_size / 2 ** 20
        loop = lib.name if lib is not None else f"no compiled loop ({note})"
        print(f"  {zip_path.name}  {size:.1f} MiB  wheels: {', '.join(wheels) or 'none'}; "
              f"{loop}")
    for zip_path, *_ in rows:
        with zipfile.ZipFile(zip_path) as z:
            bad = z.testzip()
        if bad is not None:
            sys.exit(f"build: {zip_path.name} is corrupt at {bad}")
    return 0


if __name__ == "__main__":
    sys.exit(main())

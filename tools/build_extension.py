"""Build and validate the extension zip with Blender's own tooling.

The repository keeps the manifest and ``presets/`` at the top level and the package
in ``rls_addon/``; an extension zip needs them side by side at its root, so this
stages ``rls_addon/*`` + manifest + presets into ``build/stage`` and runs
``blender_ext.py build`` and ``validate`` (shipped inside the ``bpy`` wheel) on it.

Optional compiled dependencies are bundled as unmodified PyPI wheels (Blender's rule):
``pip download`` fetches them into ``build/wheels`` (reused when already there), they
are copied to ``wheels/`` in the stage and listed in the staged manifest's ``wheels``.
Blender installs only the wheels that match the user's platform, so the extension
stays installable everywhere; where a wheel is missing, RLS falls back to BVHTree.

    python tools/build_extension.py [--out dist] [--no-wheels]
"""

import argparse
import shutil
import subprocess
import sys
import tomllib
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent

# (requirement, pip --platform tags). embreex needs only numpy, which Blender ships.
WHEELS = [
    ("embreex==4.4.0.post1", ["manylinux_2_28_x86_64"]),
]
PYTHON_VERSION = "3.11"  # Blender 4.2 .. 5.0 embed CPython 3.11


def blender_ext():
    import importlib.util

    spec = importlib.util.find_spec("bpy")  # the wheel's package, without importing it
    if spec is None or spec.origin is None:
        sys.exit("build: the bpy module is not installed (run 'make venv')")
    base = Path(spec.origin).resolve().parent
    found = sorted(base.glob("*/scripts/addons_core/bl_pkg/cli/blender_ext.py"))
    if not found:
        sys.exit(f"build: blender_ext.py not found under {base}")
    return found[-1]


def stage(dest):
    if dest.exists():
        shutil.rmtree(dest)
    ignore = shutil.ignore_patterns("__pycache__", "*.pyc")
    shutil.copytree(ROOT / "rls_addon", dest, ignore=ignore)
    shutil.copytree(ROOT / "presets", dest / "presets", ignore=ignore)
    shutil.copy2(ROOT / "blender_manifest.toml", dest / "blender_manifest.toml")
    for extra in ("LICENSE", "README.md"):
        if (ROOT / extra).exists():
            shutil.copy2(ROOT / extra, dest / extra)


def download_wheels(dest):
    """Download the bundled wheels into ``dest`` (skipped when already present)."""
    dest.mkdir(parents=True, exist_ok=True)
    found = []
    for req, platforms in WHEELS:
        name, _, version = req.partition("==")
        for plat in platforms:
            pattern = f"{name}-{version}-*{plat.split('_', 1)[0]}*.whl"
            have = [p for p in sorted(dest.glob(pattern)) if plat in p.name]
            if not have:
                cmd = [sys.executable, "-m", "pip", "download", "--quiet",
                       "--disable-pip-version-check", "--only-binary=:all:", "--no-deps",
                       "--python-version", PYTHON_VERSION, "--platform", plat,
                       "-d", str(dest), req]
                proc = subprocess.run(cmd, capture_output=True, text=True)
                if proc.returncode != 0:
                    sys.exit(f"build: could not download the {req} wheel for {plat}:\n"
                             f"{proc.stderr.strip()}\n(build without bundled wheels: "
                             "python tools/build_extension.py --no-wheels)")
                have = [p for p in sorted(dest.glob(pattern)) if plat in p.name]
            if not have:
                sys.exit(f"build: pip did not leave a {req} wheel for {plat} in {dest}")
            found.append(have[-1])
    return found


def staged_manifest(text, wheel_names):
    """The manifest text with a top-level ``wheels = [...]`` (before the first table)."""
    if not wheel_names:
        return text
    lines = ["wheels = ["] + [f'  "./wheels/{n}",' for n in wheel_names] + ["]", ""]
    out = text.splitlines()
    first_table = next((i for i, ln in enumerate(out) if ln.startswith("[")), len(out))
    return "\n".join(out[:first_table] + lines + out[first_table:]) + "\n"


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", default=str(ROOT / "dist"))
    ap.add_argument("--no-wheels", action="store_true",
                    help="do not bundle optional wheels (Embree); RLS then uses BVHTree")
    args = ap.parse_args()
    text = (ROOT / "blender_manifest.toml").read_text()
    manifest = tomllib.loads(text)
    stage_dir = ROOT / "build" / "stage"
    stage(stage_dir)
    wheels = [] if args.no_wheels else download_wheels(ROOT / "build" / "wheels")
    if wheels:
        (stage_dir / "wheels").mkdir()
        for w in wheels:
            shutil.copy2(w, stage_dir / "wheels" / w.name)
    staged = staged_manifest(text, [w.name for w in wheels])
    tomllib.loads(staged)  # still valid TOML
    (stage_dir / "blender_manifest.toml").write_text(staged)
    out = Path(args.out).resolve()
    out.mkdir(parents=True, exist_ok=True)
    zip_path = out / f"{manifest['id']}-{manifest['version']}.zip"
    if zip_path.exists():
        zip_path.unlink()
    tool = str(blender_ext())
    subprocess.run([sys.executable, tool, "build", "--source-dir", str(stage_dir),
                    "--output-filepath", str(zip_path)], check=True)
    subprocess.run([sys.executable, tool, "validate", str(zip_path)], check=True)
    print(zip_path)


if __name__ == "__main__":
    main()

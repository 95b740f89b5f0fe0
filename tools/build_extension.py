"""Build and validate the extension zip with Blender's own tooling.

The repository keeps the manifest and ``presets/`` at the top level and the package
in ``rls_addon/``; an extension zip needs them side by side at its root, so this
stages ``rls_addon/*`` + manifest + presets into ``build/stage`` and runs
``blender_ext.py build`` and ``validate`` (shipped inside the ``bpy`` wheel) on it.

    python tools/build_extension.py [--out dist]
"""

import argparse
import shutil
import subprocess
import sys
import tomllib
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent


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


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", default=str(ROOT / "dist"))
    args = ap.parse_args()
    manifest = tomllib.loads((ROOT / "blender_manifest.toml").read_text())
    stage_dir = ROOT / "build" / "stage"
    stage(stage_dir)
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

"""Compile RLS's optional native helpers (a C loop over Embree packets) in place.

    python tools/build_native.py

Needs a C compiler (gcc/cc). Without one, or on failure, it says so and exits 0: the
extension then casts Embree packets from Python (slower with several threads).
"""

import shutil
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
SRC = ROOT / "rls_addon" / "core" / "casting" / "native" / "embree_loop.c"
OUT = ROOT / "rls_addon" / "core" / "casting" / "native" / "_rls_embree_loop.so"


def main():
    cc = shutil.which("gcc") or shutil.which("cc")
    if cc is None:
        print("build_native: no C compiler found; the Python packet loop will be used")
        return 0
    if OUT.exists() and OUT.stat().st_mtime >= SRC.stat().st_mtime:
        return 0
    cmd = [cc, "-O2", "-shared", "-fPIC", "-pthread", "-o", str(OUT), str(SRC), "-lm"]
    proc = subprocess.run(cmd, capture_output=True, text=True)
    if proc.returncode != 0:
        print("build_native: compiling failed; the Python packet loop will be used\n"
              + proc.stderr, file=sys.stderr)
        return 0
    print(f"build_native: {OUT.relative_to(ROOT)}")
    return 0


if __name__ == "__main__":
    sys.exit(main())

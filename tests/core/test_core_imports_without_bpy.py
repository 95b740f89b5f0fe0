"""Guard: the core must import and run with bpy and mathutils unavailable."""

import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]

SCRIPT = r"""
import sys, importlib, pkgutil
class Block:
    def find_spec(self, name, path=None, target=None):
        if name.split('.')[0] in ('bpy', 'mathutils', 'bmesh', 'gpu'):
            raise ImportError('blocked for the guard test: ' + name)
sys.meta_path.insert(0, Block())
import rls_addon.core as core
names = [m.name for m in pkgutil.walk_packages(core.__path__, 'rls_addon.core.')]
for n in names:
    importlib.import_module(n)
assert not any(k.split('.')[0] in ('bpy', 'mathutils') for k in sys.modules)
print(len(names))
"""


def test_core_imports_without_bpy():
    out = subprocess.run([sys.executable, "-c", SCRIPT], cwd=ROOT, capture_output=True, text=True)
    assert out.returncode == 0, out.stderr
    assert int(out.stdout.strip()) >= 5

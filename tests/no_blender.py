"""A pytest plugin for the core tier: Blender's modules cannot be imported while it is
loaded (``make test-core`` runs ``pytest tests/core -p tests.no_blender``), so a core
test that needs Blender fails instead of passing only where Blender is installed."""

import sys


class _NoBlender:
    def find_spec(self, name, path=None, target=None):
        if name.split(".")[0] in ("bpy", "mathutils", "bmesh", "gpu"):
            raise ImportError(f"the core tier runs without Blender ({name} is blocked)")
        return None


if not any(m.split(".")[0] in ("bpy", "mathutils") for m in sys.modules):
    sys.meta_path.insert(0, _NoBlender())

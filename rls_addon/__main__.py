"""``python -m rls_addon ...``: the command line on the ``bpy`` module."""

import sys

from . import ensure_registered
from .cli import main

sys.exit(main(sys.argv[1:], prepare_blender=ensure_registered))

"""``python -m rls_addon ...``: the command line on the ``bpy`` module."""

import sys

from .cli import main

sys.exit(main(sys.argv[1:]))

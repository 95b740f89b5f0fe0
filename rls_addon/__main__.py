"""``python -m rls_addon ...``: the command line on the ``bpy`` module."""

from .core.stop_signals import ignore_after_end, note_from_start

note_from_start()  # first: a stop signal during the imports below ends like one later

import sys  # noqa: E402

from . import ensure_registered  # noqa: E402
from .cli import main  # noqa: E402

try:
    code = main(sys.argv[1:], prepare_blender=ensure_registered)
finally:
    ignore_after_end()  # the command has ended: Python's shutdown ends with its code
sys.exit(code)

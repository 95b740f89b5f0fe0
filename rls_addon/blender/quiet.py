"""Silence Blender's own log lines ("Read blend: ...", "Info: Saved ...") during file
operations: stdout belongs to the command line's JSON output and stderr to its
progress and one-line errors. Failures still surface, as the operator's exception.
Redirects at the file-descriptor level, since Blender writes from C."""

import contextlib
import os
import sys


@contextlib.contextmanager
def blender_output_silenced():
    sys.stdout.flush()
    try:
        fd = sys.stdout.fileno()
    except (AttributeError, OSError, ValueError):  # no real stdout (e.g. inside the UI)
        yield
        return
    saved = os.dup(fd)
    devnull = os.open(os.devnull, os.O_WRONLY)
    try:
        os.dup2(devnull, fd)
        yield
    finally:
        sys.stdout.flush()
        os.dup2(saved, fd)
        os.close(saved)
        os.close(devnull)

"""What the command line says on stderr, one whole line per write.

``print(text, file=sys.stderr)`` writes the text and its newline in two calls; a stop
signal handled between them (Python runs handlers between calls) leaves the line open,
and the next line, "rls: interrupted ...", lands on the end of a progress line. ``say``
writes the line and its newline in one call, so a stop falls before or after it."""

import sys


def say(text=""):
    """Write ``text`` and a newline to stderr in one write, flushed."""
    sys.stderr.write(f"{text}\n")
    sys.stderr.flush()

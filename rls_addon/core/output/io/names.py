"""File-name-safe names of scenes and sensors, for every file an output writes (kept
apart from ``paths``, which reads the formats' registry, so that a format's writer can
name its files without importing the registry back)."""

import re

_UNSAFE = re.compile(r"[^A-Za-z0-9._-]+")


def sanitize_name(name):
    """A file-name-safe version of a scene or sensor name (never empty, no leading dot)."""
    safe = _UNSAFE.sub("_", str(name)).lstrip(".")
    return safe or "_"

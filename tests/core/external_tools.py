"""Find the external readers and libraries that judge our files, or explain what to install.

A missing tool skips the test with what to install (``make test-core`` needs no Debian
packages), unless ``RLS_REQUIRE_TOOLS=1``: then it fails. ``make test`` installs the
tools (``make system-deps``, the requirements files) and sets it, so there nothing is
skipped. A library that no requirements file installs on this platform (embreex has
wheels for Linux x64 and Windows x64 only) is skipped either way, saying so.
"""

import importlib
import os
import platform
import re
import shutil
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]


def required():
    """True when a missing tool is a failure (``make test``), not a skip."""
    return os.environ.get("RLS_REQUIRE_TOOLS") == "1"


def missing(msg):
    """Skip (or, under ``RLS_REQUIRE_TOOLS=1``, fail) saying what to install.

    Call it from a test or a fixture (a module whose every test needs the tool: an
    autouse module-scoped fixture), never while a module is imported: a failure there is
    a collection error, which stops the whole tier."""
    if required():
        pytest.fail(msg + " (RLS_REQUIRE_TOOLS=1, as make test sets: a missing tool is a "
                    "failure, not a skip)", pytrace=False)
    pytest.skip(msg)


def require_module(name, install):
    try:
        return importlib.import_module(name)
    except ImportError:
        missing(f"Python module {name!r} is missing: pip install {install}")


def require_exe(exe, package="pcl-tools"):
    path = shutil.which(exe)
    if path is None:
        missing(f"command {exe!r} is missing: apt-get install {package}")
    return path


def installed_here(package):
    """True when a requirements*.txt installs ``package`` on this platform: its line
    has no environment marker, or its marker holds here."""
    from packaging.markers import Marker

    pattern = re.compile(rf"^{re.escape(package)}\s*(==|>=|~=|;|$)", re.IGNORECASE)
    for req in sorted(ROOT.glob("requirements*.txt")):
        for line in req.read_text().splitlines():
            line = line.split("#", 1)[0].strip()
            if pattern.match(line):
                _, _, marker = line.partition(";")
                return not marker.strip() or Marker(marker.strip()).evaluate()
    return False


def require_backend(module, package):
    """A ray-casting backend's library (``module``: one of ``core.casting``'s, with
    ``available()`` and ``unavailable_reason()``): skip or fail when it does not import,
    as ``missing``; skip either way where no requirements file installs ``package``."""
    if module.available():
        return
    why = f"{package} is not importable ({module.unavailable_reason()})"
    if not installed_here(package):
        pytest.skip(f"{why}; no requirements file installs it on {sys.platform} "
                    f"{platform.machine()}")
    missing(f"{why}: pip install -r requirements.txt -r requirements-test.txt")

"""Find the external readers that judge our files, or explain what to install.

A missing tool skips the test with the package to install (``make test-core`` needs no
Debian packages), unless ``RLS_REQUIRE_TOOLS=1``: then it fails. ``make test`` installs
the tools (``make system-deps``) and sets it, so there nothing is skipped.
"""

import importlib
import os
import shutil

import pytest


def required():
    """True when a missing tool is a failure (``make test``), not a skip."""
    return os.environ.get("RLS_REQUIRE_TOOLS") == "1"


def missing(msg):
    """Skip (or, under ``RLS_REQUIRE_TOOLS=1``, fail) saying what to install."""
    if required():
        pytest.fail(msg + " (RLS_REQUIRE_TOOLS=1: make test installs it with 'make "
                    "system-deps')", pytrace=False)
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

"""Find the external readers that judge our files, or explain what to install.

A missing tool fails the test with the package to install, unless
RLS_ALLOW_MISSING_TOOLS=1, which turns it into a skip.
"""

import importlib
import os
import shutil

import pytest


def _missing(msg):
    if os.environ.get("RLS_ALLOW_MISSING_TOOLS") == "1":
        pytest.skip(msg)
    pytest.fail(msg + " (set RLS_ALLOW_MISSING_TOOLS=1 to skip instead)", pytrace=False)


def require_module(name, install):
    try:
        return importlib.import_module(name)
    except ImportError:
        _missing(f"Python module {name!r} is missing: pip install {install}")


def require_exe(exe, package="pcl-tools"):
    path = shutil.which(exe)
    if path is None:
        _missing(f"command {exe!r} is missing: apt-get install {package}")
    return path

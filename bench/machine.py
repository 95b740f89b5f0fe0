"""The machine a bench run measured on: processor, cores, memory, system, load and the
versions of what was timed (the report's header)."""

import datetime
import os
import platform

import numpy as np


def require_compiled_loop():
    """Exit when Embree's compiled loop is not what the run would time: a stale or
    missing build makes every scan fall back to packets cast from Python (slower, and
    moving objects cast the portable way), so the figures would describe the fallback
    and not the product. ``make bench`` builds it first (``make native``)."""
    import sys

    from rls_addon.core.casting import embree, embree_loop

    if embree.available() and embree_loop._native_loop() is None:
        sys.exit("bench: the compiled ray loop is not in use ("
                 + embree_loop.native_loop_error() + "); build it with make native "
                 "(or .venv/bin/python tools/build_native.py) and run the bench again")


def machine_info():
    cpu = platform.processor() or platform.machine()
    try:
        for line in open("/proc/cpuinfo"):
            if line.startswith("model name"):
                cpu = line.split(":", 1)[1].strip()
                break
    except OSError:
        pass
    mem = None
    try:
        for line in open("/proc/meminfo"):
            if line.startswith("MemTotal"):
                mem = int(line.split()[1]) / 1024 ** 2
    except OSError:
        pass
    try:
        cores = len(os.sched_getaffinity(0))
    except AttributeError:
        cores = os.cpu_count()
    versions = {"python": platform.python_version(), "numpy": np.__version__}
    from importlib.metadata import PackageNotFoundError, version

    for pkg in ("bpy", "embreex", "open3d", "matplotlib"):
        try:
            versions[pkg] = version(pkg)
        except PackageNotFoundError:
            versions[pkg] = "missing"
    return {"cpu": cpu, "cores": cores, "memory_gib": mem, "os": platform.platform(),
            "loadavg_start": os.getloadavg()[0],
            "date": datetime.datetime.now().strftime("%Y-%m-%d %H:%M"), "versions": versions}

"""What a Dask worker runs for a sharded run (``commands.distribute`` submits these).

A worker process opens the .blend once and keeps it, with its scene source (meshes
read once) and its scan sessions (prepared scenes, a still sensor's kept cast), for
every piece of the run it is given: a piece costs its rays, not a scene load. Pieces
are complete runs of their own (``core.run.ScanRun`` with ``piece=True``), so their
files are written, atomically, where the whole run would write them.
"""

import os
from dataclasses import dataclass, field

_STATE = {}


def _import_bpy():
    """Import the bpy module in a worker. A local cluster's workers start with the
    parent's ``sys.path``, which (once the parent imported bpy) lists Blender's script
    folders first: their pure-Python ``bpy`` package would shadow the compiled module
    and fail ('No module named _bpy'). Those folders go until the module is in; it
    puts them back itself."""
    import sys

    if "bpy" not in sys.modules:
        sys.path[:] = [p for p in sys.path
                       if not p.replace("\\", "/").rstrip("/").endswith(("/scripts/modules",
                                                                          "/scripts/startup",
                                                                          "/scripts/addons_core"))]
    import bpy

    return bpy


def _open(blend, prepare_blender):
    """The worker's scene for ``blend``: opened on first use, kept while the file does
    not change. ``prepare_blender`` (the entry point's ``ensure_registered``, sent
    with the piece) registers the extension in this process."""
    bpy = _import_bpy()

    path = os.path.abspath(blend)
    try:
        key = (path, os.path.getmtime(path))
    except OSError:
        from ..core.errors import InputError

        raise InputError(f"scene file not found on worker {os.uname().nodename}: {path} "
                         "(workers need the scene on a path they share)") from None
    if _STATE.get("key") != key:
        from ..blender.files import open_blend
        from ..blender.source import BlenderScene

        _STATE.clear()
        open_blend(path)
        prepare_blender()
        _STATE.update(key=key, source=BlenderScene(bpy.context.scene, edited=False),
                      sessions={}, studies={})
    return _STATE


@dataclass
class PieceResult:
    steps: list
    id_map: dict
    warnings: list = field(default_factory=list)
    notices: list = field(default_factory=list)
    builds: int = 0
    worker: str = ""


def scan_piece(blend, jobs, frames, writer, prepare_blender):
    """Scan ``frames`` x ``jobs`` (``core.run.SensorJob``) of ``blend`` with ``writer``;
    returns a ``PieceResult`` (the steps, for the run to absorb)."""
    from ..core.scan.run import ScanRun

    state = _open(blend, prepare_blender)
    run = ScanRun(state["source"], jobs, frames, writer=writer, sessions=state["sessions"],
                  piece=True)
    run.run()
    return PieceResult(run.outputs, run.id_map, run.warnings, list(getattr(writer, "notices", [])),
                       run.structure_builds, f"{os.uname().nodename}:{os.getpid()}")


def study_piece(blend, cfg, indices, prepare_blender):
    """Scan the candidates ``indices`` of the study ``cfg`` of ``blend``; returns their
    ``core.study.scanner.CandidateScan`` s (the worker keeps the study's prepared scene)."""
    from ..core.study.scanner import StudyScanner, study_inputs

    state = _open(blend, prepare_blender)  # first: it imports bpy the way a worker must
    from ..blender.study import BlenderStudyScene

    key = repr(cfg)
    got = state["studies"].get(key)
    if got is None:
        scene = BlenderStudyScene(_import_bpy().context.scene)
        inputs = study_inputs(scene, cfg)
        scanner = StudyScanner(scene, cfg, inputs.preset, inputs.polygon,
                                          inputs.layout, inputs.candidates)
        got = state["studies"][key] = (scanner, inputs.candidates)
    scanner, cands = got
    return [scanner.scan(cands[i]) for i in indices]

"""Operators: thin wrappers that read properties, call the Blender adapters and report
domain errors, one module per concern (objects, scan, metrics, presets, traffic,
dataset, roads, evaluate; running: what operators that run a scan share). Every
operator also runs without a window (``blender -b``, the ``bpy`` module): the
frame-range scan then runs straight through in ``execute()``."""

from . import dataset, evaluate, metrics, objects, presets, roads, scan, traffic
from .scan import LAST_RUN, RLS_OT_scan_all, RLS_OT_scan_frame, RLS_OT_scan_range

CLASSES = (objects.CLASSES + scan.CLASSES + metrics.CLASSES + presets.CLASSES + traffic.CLASSES
           + dataset.CLASSES + roads.CLASSES + evaluate.CLASSES)

# What scripts and tests read: the last scan's summary and the scan operators.
__all__ = ["CLASSES", "LAST_RUN", "RLS_OT_scan_all", "RLS_OT_scan_frame", "RLS_OT_scan_range"]

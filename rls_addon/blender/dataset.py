"""A dataset export of a Blender scene: the core's ``ScanRun`` of its LiDARs with the
layout's writer, as ``DatasetSettings`` say (``rls dataset`` and *File > Export > RLS
Dataset* both run this)."""

from ..core.errors import SceneError
from ..core.labels import label_ids, label_name
from ..core.scan.run import ScanRun
from .labels import object_label
from .sensor import find_lidar, lidar_objects, read_settings, sensor_job
from .source import BlenderScene


def carrier_of(obj, classes):
    """The object a LiDAR rides on, when it is an object of ``classes`` (its parent, or
    a parent's parent): that vehicle is the LiDAR's OPV2V agent."""
    o = obj.parent
    while o is not None:
        if object_label(o) in classes:
            return o.name
        o = o.parent
    return None


def dataset_run(scene, settings, progress=None, cancelled=None, edited=True):
    """(``ScanRun``, its writer) exporting ``scene`` as ``settings``
    (``core.output.datasets.settings.DatasetSettings``) say; nothing is scanned yet.
    ``edited=False`` for a background Blender nobody edits (the command line)."""
    sensors = [find_lidar(scene, n) for n in settings.sensors] or lidar_objects(scene)
    if not sensors:
        raise SceneError(f"scene '{scene.name}' has no LiDAR objects (add one with Add > "
                         "LiDAR, or rls lidar add)")
    classes = label_ids(settings.classes)
    changes = settings.scan_changes(label_name(c) for c in classes)
    jobs = [sensor_job(o, read_settings(o).override(**changes)) for o in sensors]
    carriers = ({o.name: carrier_of(o, set(classes)) for o in sensors}
                if settings.layout == "opv2v" else {})
    writer = settings.writer(scene.name, [o.name for o in sensors], carriers)
    run = ScanRun(BlenderScene(scene, edited=edited), jobs, list(settings.frames),
                  writer=writer, progress=progress, cancelled=cancelled)
    return run, writer

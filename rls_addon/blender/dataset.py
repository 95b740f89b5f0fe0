"""A dataset export of a Blender scene: the core's ``ScanRun`` of its LiDARs with the
layout's writer, as ``DatasetSettings`` say (``rls dataset`` and *File > Export > RLS
Dataset* both run this)."""

from ..core.errors import SceneError
from ..core.labels import label_ids, label_name
from ..core.scan.background_sweeps import background_runs
from ..core.scan.run import ScanRun
from .labels import object_label, road_user_sizes
from .sensor import find_lidar, lidar_objects, read_settings, sensor_job
from .source import BlenderScene


def carrier_of(obj, classes):
    """The object a LiDAR rides on, when it is an object of ``classes`` (its parent, or
    a parent's parent): that vehicle is the LiDAR's OPV2V agent, and is left out of its
    KITTI labels."""
    o = obj.parent
    while o is not None:
        if object_label(o) in classes:
            return o.name
        o = o.parent
    return None


def scene_class_types(scene):
    """{class name: [{"size": [l, w, h], "objects": n}, ...]}: the scene's own types of
    road users (``priors.scene_types``), the commonest first, for dataset.json."""
    from ..core.evaluate.detector.priors import scene_types

    types = scene_types(*road_user_sizes(scene))
    return {label_name(k): [{"size": list(r[:3]), "objects": r[3]} for r in rows]
            for k, rows in sorted(types.items())}


def dataset_run(scene, settings, progress=None, cancelled=None, edited=True,
                sweep_progress=None, write_behind=False):
    """(``ScanRun``, its writer, (background sweep runs, the scene without road users,
    notices)) exporting ``scene`` as ``settings``
    (``core.output.datasets.settings.DatasetSettings``) say; nothing is scanned yet, and
    the background sweeps (``core.scan.background_sweeps``) run first
    (``background_sweeps.run_all``). ``edited=False`` for a background Blender nobody
    edits (the command line); ``write_behind``: the frames' files written on a thread
    behind the scan (``core.output.io.behind``; the command line)."""
    sensors = [find_lidar(scene, n) for n in settings.sensors] or lidar_objects(scene)
    if not sensors:
        raise SceneError(f"scene '{scene.name}' has no LiDAR objects (add one with Add > "
                         "LiDAR, or rls lidar add)")
    classes = label_ids(settings.classes)
    changes = settings.scan_changes(label_name(c) for c in classes)
    jobs = [sensor_job(o, read_settings(o).override(**changes)) for o in sensors]
    # the vehicle each LiDAR rides on: OPV2V's agent, and what KITTI leaves unlabelled
    carriers = {o.name: carrier_of(o, set(classes)) for o in sensors}
    writer = settings.writer(scene.name, [o.name for o in sensors], carriers,
                             background=write_behind)
    writer.class_types = scene_class_types(scene)
    source = BlenderScene(scene, edited=edited)
    # the background sweeps' runs are made first: their files are checked too before
    # anything is scanned
    background = background_runs(source, jobs, settings.frames[0], settings.background_sweeps,
                                 writer.background_writer, progress=sweep_progress,
                                 labels=[label_name(c) for c in classes], cancelled=cancelled)
    run = ScanRun(source, jobs, list(settings.frames), writer=writer, progress=progress,
                  cancelled=cancelled)
    return run, writer, background

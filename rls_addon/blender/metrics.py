"""*Compute Metrics* over the scene: the LiDARs' preview points as clouds, and the
density chart the command line draws (``rls metrics --density-png``:
``core/metrics/charts.py``) as an image in the .blend."""

import numpy as np

from ..core.metrics.charts import density_png, density_title, sensor_marker
from ..core.points import empty_points
from .files import scene_title
from .images import image_from_png
from .preview import preview_object, preview_world_points
from .sensor import lidar_objects


def preview_clouds(scene):
    """([world-frame points with x, y, z and label], [LiDAR objects]) of every LiDAR of
    ``scene`` whose preview holds points."""
    clouds, lidars = [], []
    for obj in lidar_objects(scene):
        prev = preview_object(obj)
        if prev is None or len(prev.data.vertices) == 0:
            continue
        co, labels = preview_world_points(prev)
        pts = empty_points(len(co))
        pts["x"], pts["y"], pts["z"] = co[:, 0], co[:, 1], co[:, 2]
        pts["label"] = labels
        clouds.append(pts)
        lidars.append(obj)
    return clouds, lidars


def sensor_markers(lidars):
    """(name, x, y, heading) of each LiDAR object for the density chart."""
    out = (sensor_marker(o.name, np.array(o.matrix_world, dtype=np.float64)) for o in lidars)
    return [m for m in out if m is not None]


def density_chart_title(scene, lob_name, names, result):
    """The chart's title, as ``rls metrics`` words it: the sensors, the region and the
    scene's file, then InfraD and InfraNUC."""
    sensors = " + ".join(names) if len(names) <= 3 else f"{len(names)} LiDARs: {names[0]}, {names[1]}, ..."
    detail = (f"{result.n_points:,} {'/'.join(result.labels)} points in {result.area_m2:.0f} m², "
              f"{result.disks} disks of r {result.radius_m:g} m")
    return density_title(f"{sensors}, region {lob_name} in {scene_title(scene)}",
                         result.infra_d, result.infra_nuc, detail)


def density_image(scene, lob_name, lidars, result):
    """(image, notice): the density chart of ``result`` (an ``InfraLOBResult``) as the
    image ``RLS density <region>``; without matplotlib the bare map and a notice."""
    title = density_chart_title(scene, lob_name, [o.name for o in lidars], result)
    png, notice = density_png(result.density, title, polygon=result.polygon_xy,
                              sensors=sensor_markers(lidars))
    img = image_from_png(f"RLS density {lob_name}", png)
    img["rls_title"] = title
    return img, notice

"""Scanning a Blender scene: extraction + BVHTree + the core engine, for one LiDAR."""

from ..core.engine import scan_frame
from .bvh_caster import BVHCaster
from .extract import extract_geometry
from .sensor import scan_inputs, sensor_pose


def scan_lidar(depsgraph, obj, frame, caster_factory=BVHCaster, settings=None):
    """Scan one frame of LiDAR ``obj`` in an evaluated ``depsgraph`` (already at ``frame``).

    Returns (ScanResult, info dict for the sidecar)."""
    preset, obj_settings = scan_inputs(obj)
    settings = settings or obj_settings
    pose = sensor_pose(obj.evaluated_get(depsgraph))
    rmax = settings.max_range_m or preset.range.max_m
    geometry, stats = extract_geometry(depsgraph, centre=pose[:3, 3], max_range=rmax,
                                       exclude={obj.name})
    result = scan_frame(geometry, preset.pattern(), pose, preset, settings, caster_factory,
                        frame=frame, sensor=obj.name)
    info = {
        "device": {"id": preset.id, "name": preset.name, "source": preset.source},
        "sensor": obj.name,
        "frame": frame,
        "frame_space": settings.frame_space,
        "sensor_to_world": pose.tolist(),
        "seed": settings.seed,
        "effects": {"noise": settings.noise, "dropout": settings.dropout,
                    "range_m": [preset.range.min_m, rmax],
                    "noise_sigma_m": preset.range.noise_sigma_m if settings.noise else 0.0},
        "labels": {str(k): v for k, v in geometry.label_map().items()},
        "rays": result.rays,
        "points": int(len(result.points)),
        "triangles_cast": result.triangles,
        "objects_read": stats["objects"],
        "objects_culled_by_range": stats["culled_by_range"],
        "warnings": result.warnings,
    }
    return result, info


def save_scan(result, info, out_dir, template, fmt, scene_name, overwrite=False):
    """Write the points and their JSON sidecar; return the cloud's path."""
    from ..core.io import output_path, write_cloud, write_sidecar
    from ..version import VERSION

    path = output_path(out_dir, template, scene=scene_name, sensor=info["sensor"],
                       frame=info["frame"], fmt=fmt)
    write_cloud(path, result.points, fmt=fmt, overwrite=overwrite)
    write_sidecar(path, dict(info, format=fmt, software=f"rls {VERSION}"), overwrite=overwrite)
    return path

"""Scanning a Blender scene: extraction + BVHTree + the core engine."""

from ..core.engine import PreparedScene, resolve_range, scan_frame
from .bvh_caster import BVHCaster
from .extract import extract_geometry
from .sensor import scan_inputs, sensor_pose


class ScanSession:
    """Scans several frames and sensors, building the ray-casting structure only when
    the geometry a sensor sees changed (same digest: the built structure is reused)."""

    def __init__(self, caster_factory=BVHCaster):
        self.caster_factory = caster_factory
        self._prepared = {}
        self.builds = 0

    def prepared(self, geometry, centre, reach):
        key = (geometry.fingerprint(), tuple(centre), reach)
        scene = self._prepared.get(key)
        if scene is None:
            if len(self._prepared) >= 4:  # bounded: a moving sensor sees new geometry
                self._prepared.pop(next(iter(self._prepared)))
            scene = PreparedScene(geometry, centre, reach, self.caster_factory)
            self._prepared[key] = scene
            self.builds += 1
        return scene

    def scan(self, depsgraph, obj, frame, settings=None):
        """Scan one frame of LiDAR ``obj`` in ``depsgraph`` (already at ``frame``).

        Returns (ScanResult, info dict for the sidecar)."""
        preset, obj_settings = scan_inputs(obj)
        settings = settings or obj_settings
        pose = sensor_pose(obj.evaluated_get(depsgraph))
        _, rmax = resolve_range(preset, settings)
        centre = pose[:3, 3]
        geometry, stats = extract_geometry(depsgraph, centre=centre, max_range=rmax,
                                           exclude={obj.name})
        scene = self.prepared(geometry, centre, rmax)
        result = scan_frame(scene, preset.pattern(), pose, preset, settings,
                            frame=frame, sensor=obj.name)
        info = {
            "device": {"id": preset.id, "name": preset.name, "source": preset.source},
            "sensor": obj.name,
            "frame": frame,
            "frame_space": settings.frame_space,
            "sensor_to_world": pose.tolist(),
            "seed": settings.seed,
            "effects": {"noise": settings.noise, "dropout": settings.dropout,
                        "range_m": [resolve_range(preset, settings)[0], rmax],
                        "noise_sigma_m": preset.range.noise_sigma_m if settings.noise else 0.0},
            "labels": {str(k): v for k, v in geometry.label_map().items()},
            "backend": scene.backend,
            "rays": result.rays,
            "points": int(len(result.points)),
            "triangles_cast": result.triangles,
            "objects_read": stats["objects"],
            "objects_culled_by_range": stats["culled_by_range"],
            "warnings": result.warnings,
        }
        return result, info


def scan_lidar(depsgraph, obj, frame, caster_factory=BVHCaster, settings=None):
    """Scan one frame of one LiDAR without reuse across calls (see ``ScanSession``)."""
    return ScanSession(caster_factory).scan(depsgraph, obj, frame, settings)


def save_scan(result, info, out_dir, template, fmt, scene_name, overwrite=False):
    """Write the points and their JSON sidecar; return the cloud's path."""
    from ..core.io import output_path, write_cloud, write_sidecar
    from ..version import VERSION

    path = output_path(out_dir, template, scene=scene_name, sensor=info["sensor"],
                       frame=info["frame"], fmt=fmt)
    write_cloud(path, result.points, fmt=fmt, overwrite=overwrite)
    write_sidecar(path, dict(info, format=fmt, software=f"rls {VERSION}"), overwrite=overwrite)
    return path

"""*Compute Metrics*: InfraD, InfraNUC and the density map over the preview points of
every LiDAR in the InfraLOB: the chart the command line draws."""

import bpy

from ..blender.metrics import density_image, preview_clouds
from ..blender.region import lob_polygon_world
from ..blender.values import typed_float
from ..core.errors import RLSError
from ..core.metrics.infra import infra_lob_metrics
from .common import _poll_lob, cancelled, find_lob


class RLS_OT_compute_metrics(bpy.types.Operator):
    """Compute InfraD and InfraNUC over the InfraLOB from the preview points of every
    LiDAR in the scene (world frame), and make the density map image"""

    bl_idname = "rls.compute_metrics"
    bl_label = "Compute Metrics"
    bl_options = {"REGISTER", "UNDO"}  # makes the density map image

    poll = classmethod(_poll_lob)

    def execute(self, context):
        sc = context.scene
        rs = sc.rls
        lob = find_lob(context)
        clouds, lidars = preview_clouds(sc)
        if not clouds:
            return cancelled(self, "No LiDAR points to measure: scan a frame first "
                                   "(Scan Frame or Scan All LiDARs)")
        try:
            res = infra_lob_metrics(clouds, lob_polygon_world(lob), labels=rs.metric_labels,
                                    disks=rs.metric_disks, radius=typed_float(rs.metric_radius),
                                    seed=rs.metric_seed, cell=typed_float(rs.metric_cell))
        except RLSError as exc:
            return cancelled(self, f"{lob.name}: {exc}")
        img, notice = density_image(sc, lob.name, lidars, res)
        if notice:
            self.report({"WARNING"}, notice)
        rs.has_metrics = True
        rs.infra_d, rs.infra_nuc = res.infra_d, res.infra_nuc
        rs.metric_points, rs.metric_area = res.n_points, res.area_m2
        rs.metric_lob_name = lob.name
        rs.metric_sensors = ", ".join(o.name for o in lidars)
        rs.metric_image = img
        rs.lob = lob
        self.report({"INFO"}, f"{lob.name}: InfraD {res.infra_d:.3f} pts/m^2, "
                              f"InfraNUC {res.infra_nuc:.4f} ({res.n_points} points)")
        return {"FINISHED"}


CLASSES = (
    RLS_OT_compute_metrics,
)

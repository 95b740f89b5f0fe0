"""The *Detect and Evaluate* panel (Scene properties): the dataset, where detections go,
what counts, the button, and the last result's AP table (stored properties only)."""

import bpy

AP_HELP = "AP: fractions of 1; R40: KITTI's 40 recall points; VOC: all-point, as OpenCOOD"


def _ap(value):
    return "-" if value < 0 else f"{value:.3f}"


class SCENE_PT_rls_evaluate(bpy.types.Panel):
    bl_label = "RLS Detect and Evaluate"
    bl_space_type = "PROPERTIES"
    bl_region_type = "WINDOW"
    bl_context = "scene"
    bl_options = {"DEFAULT_CLOSED"}

    def draw(self, context):
        layout = self.layout
        layout.use_property_split = True
        layout.use_property_decorate = False
        rs = context.scene.rls
        ev = rs.evaluation
        layout.prop(ev, "dataset")
        layout.prop(ev, "detections")
        layout.prop(ev, "background_frames")
        row = layout.row(heading="Region")
        row.prop(ev, "use_region", text="")
        sub = row.row()
        sub.active = ev.use_region
        sub.prop(rs, "lob", text="")
        layout.prop(ev, "min_points")
        layout.prop(ev, "overwrite")
        layout.operator("rls.detect_evaluate", icon="VIEWZOOM")
        if not ev.has_result:
            return
        box = layout.box()
        box.label(text=ev.summary, icon="INFO")
        grid = box.grid_flow(row_major=True, columns=7, even_columns=False, align=True)
        for text in ("Class", "IoU", "AP R40", "AP VOC", "TP", "FP", "GT"):
            grid.label(text=text)
        for r in ev.rows:
            for text in (r.name, f"{r.kind} {r.iou:g}", _ap(r.ap_r40), _ap(r.ap_voc),
                         str(r.tp), str(r.fp), str(r.gt)):
                grid.label(text=text)
        box.label(text=AP_HELP)
        box.prop(ev, "result_path", text="Result")

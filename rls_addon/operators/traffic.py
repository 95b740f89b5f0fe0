"""*Import SUMO Traffic*: SUMO floating-car data as animated, labelled objects in the
current scene (what ``rls traffic import`` does to a copy of a .blend). The file is
read and checked before anything is added, so bad input leaves the scene as it was."""

import bpy
from bpy.props import BoolProperty, FloatProperty, FloatVectorProperty, StringProperty

from ..core.errors import RLSError
from .common import cancelled


class RLS_OT_import_sumo_traffic(bpy.types.Operator):
    """Import SUMO floating-car data (sumo --fcd-output): one animated object per vehicle
    and person, sized by its vType, labelled vehicle, cyclist or pedestrian"""

    bl_idname = "rls.import_sumo_traffic"
    bl_label = "Import SUMO Traffic"
    bl_options = {"REGISTER", "UNDO"}

    filepath: StringProperty(subtype="FILE_PATH", description="SUMO FCD output (.xml)")
    filter_glob: StringProperty(default="*.xml", options={"HIDDEN"},
                               description="Show SUMO FCD files (XML) in the file browser")
    vtypes: StringProperty(name="vTypes", subtype="FILE_PATH",
                           description="Route or additional file with the <vType>s (empty: "
                                       "FCD.vtypes.xml beside the FCD, else SUMO's built-in "
                                       "types)")
    origin: FloatVectorProperty(name="Origin", size=2, default=(0.0, 0.0), unit="LENGTH",
                                description="Network coordinates placed at the scene's origin "
                                            "(left unset: the origin the scene records, from "
                                            "rls scene from-net, else 0, 0)")
    use_begin: BoolProperty(name="Begin", default=False,
                            description="Choose the simulation time of the first frame")
    begin: FloatProperty(name="Begin (s)", default=0.0, min=0.0,
                         description="Simulation time at the scene's first frame")
    use_end: BoolProperty(name="End", default=False,
                          description="Choose the last simulation time keyed")
    end: FloatProperty(name="End (s)", default=60.0, min=0.0,
                       description="Last simulation time keyed")

    def invoke(self, context, event):
        context.window_manager.fileselect_add(self)
        return {"RUNNING_MODAL"}

    def execute(self, context):
        from ..blender.traffic import import_traffic, traffic_origin
        from ..core.traffic.fcd import load

        if not self.filepath:
            return cancelled(self, "Choose a SUMO FCD file to import")
        begin = self.begin if self.use_begin else None
        end = self.end if self.use_end else None
        wm = context.window_manager
        try:
            fcd, types = load(bpy.path.abspath(self.filepath),
                              [bpy.path.abspath(self.vtypes)] if self.vtypes else [],
                              begin, end)
            total = max(1, len(fcd.tracks))
            wm.progress_begin(0, total)
            try:
                origin = traffic_origin(context.scene, tuple(self.origin)
                                        if self.properties.is_property_set("origin") else None)
                info = import_traffic(context.scene, fcd, types, origin=origin,
                                      begin=begin, end=end,
                                      progress=lambda done, n: wm.progress_update(done))
            finally:
                wm.progress_end()
        except RLSError as exc:
            return cancelled(self, exc)
        for notice in info["notices"]:
            self.report({"WARNING"}, notice)
        self.report({"INFO"}, f"Imported {info['vehicle']} vehicles, {info['cyclist']} "
                              f"cyclists and {info['pedestrian']} pedestrians over frames "
                              f"{info['first_frame']}-{info['last_frame']}")
        return {"FINISHED"}


def draw_import_menu(self, context):
    self.layout.operator(RLS_OT_import_sumo_traffic.bl_idname, text="SUMO Traffic (.xml)")


CLASSES = (RLS_OT_import_sumo_traffic,)

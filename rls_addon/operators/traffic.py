"""*Import SUMO Traffic*: SUMO floating-car data as animated, labelled objects in the
current scene (what ``rls traffic import`` does to a copy of a .blend). The file is
read and checked before anything is added, so bad input leaves the scene as it was.
*Generate SUMO Traffic*, beside it: random traffic over a SUMO network simulated by
SUMO (``rls traffic generate``, the same core call and so the same files), imported
into the scene when asked."""

import os

import bpy
from bpy.props import (BoolProperty, EnumProperty, FloatProperty, FloatVectorProperty,
                       IntProperty, StringProperty)

from ..core.errors import RLSError
from .common import cancelled, status_text


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


PEDESTRIAN_ITEMS = [("auto", "Where Sidewalks", "Persons walk where the network has sidewalks"),
                    ("yes", "Yes", "Persons walk"), ("no", "No", "No persons")]


def fcd_path_for(net):
    """Where generated traffic goes by default: NET.fcd.xml beside NET.net.xml."""
    base = net[:-len(".net.xml")] if net.lower().endswith(".net.xml") else os.path.splitext(net)[0]
    return base + ".fcd.xml"


class RLS_OT_generate_sumo_traffic(bpy.types.Operator):
    """Make random traffic over a SUMO network and simulate it with SUMO (what rls
    traffic generate writes: the FCD, its vTypes and routes), then import it into this
    scene. Needs SUMO (pip install eclipse-sumo, or SUMO_HOME)"""

    bl_idname = "rls.generate_sumo_traffic"
    bl_label = "Generate SUMO Traffic"
    bl_options = {"REGISTER", "UNDO"}

    filepath: StringProperty(subtype="FILE_PATH", description="SUMO network (.net.xml)")
    filter_glob: StringProperty(default="*.net.xml;*.xml", options={"HIDDEN"},
                                description="Show SUMO network files in the file browser")
    fcd: StringProperty(name="FCD Output", subtype="FILE_PATH",
                        description="The FCD file to write (empty: NET.fcd.xml beside the "
                                    "network); its .vtypes.xml and .rou.xml go beside it")
    duration: FloatProperty(name="Duration", default=60.0, min=0.1, unit="TIME_ABSOLUTE",
                            description="Seconds of traffic to simulate")
    rate: FloatProperty(name="Vehicles per Hour", default=600.0, min=1.0,
                        description="Vehicles inserted per hour")
    seed: IntProperty(name="Seed", default=1, min=0,
                      description="Random trips' seed: the same seed, the same files")
    step: FloatProperty(name="Step", default=0.1, min=0.001, unit="TIME_ABSOLUTE",
                        description="SUMO's step length and FCD period")
    pedestrians: EnumProperty(name="Pedestrians", items=PEDESTRIAN_ITEMS, default="auto",
                              description="Persons walking")
    ped_rate: FloatProperty(name="Persons per Hour", default=0.0, min=0.0,
                            description="Persons per hour (0: a quarter of the vehicles' rate)")
    overwrite: BoolProperty(name="Overwrite", default=False,
                            description="Replace existing output files")
    import_traffic: BoolProperty(name="Import into Scene", default=True,
                                 description="Import the generated traffic into this scene")

    def invoke(self, context, event):
        context.window_manager.fileselect_add(self)
        return {"RUNNING_MODAL"}

    def execute(self, context):
        from ..core.traffic.sumo_run import GenerateSettings, generate_traffic

        if not self.filepath:
            return cancelled(self, "Choose a SUMO network file (.net.xml)")
        net = bpy.path.abspath(self.filepath)
        out = bpy.path.abspath(self.fcd) if self.fcd else fcd_path_for(net)
        status_text(context, f"Running SUMO over {os.path.basename(net)} ...")
        try:
            # rounded: float32 properties would hand SUMO 0.10000000149 for 0.1
            info = generate_traffic(GenerateSettings(
                net=net, out=out, duration=round(self.duration, 6), rate=round(self.rate, 6),
                seed=self.seed, step=round(self.step, 6), pedestrians=self.pedestrians,
                ped_rate=round(self.ped_rate, 6) or None, overwrite=self.overwrite))
        except RLSError as exc:
            return cancelled(self, exc)
        finally:
            status_text(context, None)
        self.report({"INFO"}, f"SUMO traffic: {info['vehicles']} vehicles, {info['persons']} "
                              f"persons over {self.duration:g} s written to {out}")
        if not self.import_traffic:
            return {"FINISHED"}
        result = bpy.ops.rls.import_sumo_traffic(filepath=out)
        return {"FINISHED"} if result == {"FINISHED"} else {"CANCELLED"}


def draw_import_menu(self, context):
    self.layout.operator(RLS_OT_import_sumo_traffic.bl_idname, text="SUMO Traffic (.xml)")
    self.layout.operator(RLS_OT_generate_sumo_traffic.bl_idname,
                         text="SUMO Traffic, Generated (.net.xml)")


CLASSES = (RLS_OT_import_sumo_traffic, RLS_OT_generate_sumo_traffic)

"""*File > Import > SUMO Network as Scene*: a new scene in this file built from a SUMO
road network, as ``rls scene from-net`` builds its .blend (the same layout and builder:
``core.roads.layout.network_layout``, ``blender.roads.build_roads``). The network is
read and checked before anything is added, so bad input leaves the file as it was."""

import os

import bpy
from bpy.props import EnumProperty, StringProperty

from ..core.errors import RLSError
from ..core.roads.layout import ORIGINS
from .common import cancelled, status_text

_ORIGIN_TEXT = {
    "net": ("Network", "The scene's (0, 0) is the network's: scene x, y = SUMO's x, y"),
    "junction": ("Junction", "The chosen junction at the scene's (0, 0)"),
}
ORIGIN_ITEMS = [(o, *_ORIGIN_TEXT[o]) for o in ORIGINS]  # rls scene from-net --origin


def scene_name_for(path):
    """'crossing' for crossing.net.xml."""
    name = os.path.basename(path)
    for ext in (".net.xml", ".xml"):
        if name.lower().endswith(ext):
            return name[:-len(ext)] or "SUMO network"
    return name


class RLS_OT_import_sumo_network(bpy.types.Operator):
    """Build a new scene from a SUMO road network (.net.xml): roads, crossings, raised
    sidewalks and kerbs, a mount pole at each corner of one junction and an InfraLOB
    over it (what rls scene from-net writes)"""

    bl_idname = "rls.import_sumo_network"
    bl_label = "Import SUMO Network as Scene"
    bl_options = {"REGISTER", "UNDO"}

    filepath: StringProperty(subtype="FILE_PATH", description="SUMO network (.net.xml)")
    filter_glob: StringProperty(default="*.net.xml;*.xml", options={"HIDDEN"},
                                description="Show SUMO network files in the file browser")
    junction: StringProperty(name="Junction",
                             description="The junction the mounts and the InfraLOB are at "
                                         "(empty: the largest by area)")
    origin: EnumProperty(name="Origin", items=ORIGIN_ITEMS, default="net",
                         description="Where the scene's (0, 0) is")

    def invoke(self, context, event):
        context.window_manager.fileselect_add(self)
        return {"RUNNING_MODAL"}

    def execute(self, context):
        from ..blender.roads import build_roads
        from ..core.roads.layout import network_layout

        if not self.filepath:
            return cancelled(self, "Choose a SUMO network file (.net.xml)")
        path = bpy.path.abspath(self.filepath)
        try:
            _, layout = network_layout(path, self.junction.strip() or None, self.origin)
        except RLSError as exc:
            return cancelled(self, exc)
        scene = bpy.data.scenes.new(scene_name_for(path))
        try:
            info = build_roads(scene, layout,
                               progress=lambda text: status_text(context, f"SUMO network: {text}"))
        except RLSError as exc:
            bpy.data.scenes.remove(scene)
            return cancelled(self, exc)
        finally:
            status_text(context, None)
        if context.window is not None:
            context.window.scene = scene
        self.report({"INFO"}, f"Scene '{scene.name}': junction {info['junction']}, "
                              f"{len(info['mounts'])} mounts, {info['triangles']} triangles")
        return {"FINISHED"}


def draw_import_menu(self, context):
    self.layout.operator(RLS_OT_import_sumo_network.bl_idname,
                         text="SUMO Network as Scene (.net.xml)")


CLASSES = (RLS_OT_import_sumo_network,)

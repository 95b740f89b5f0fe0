"""*File > Import > SUMO Network as Scene*: a new scene in this file built from a SUMO
road network, as ``rls scene from-net`` builds its .blend (the same core entry point,
``core.roads.scene.scene_from_net``, with Blender's builder). The network is read and
checked before anything is added, so bad input leaves the file as it was."""

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
                                         "(empty: the signalised one with the most incoming lanes)")
    origin: EnumProperty(name="Origin", items=ORIGIN_ITEMS, default="net",
                         description="Where the scene's (0, 0) is")

    def invoke(self, context, event):
        context.window_manager.fileselect_add(self)
        return {"RUNNING_MODAL"}

    def execute(self, context):
        from ..blender.roads import BlenderRoadScene
        from ..core.roads.scene import FromNetSettings, scene_from_net

        if not self.filepath:
            return cancelled(self, "Choose a SUMO network file (.net.xml)")
        path = bpy.path.abspath(self.filepath)
        settings = FromNetSettings(net=path, out=None, junction=self.junction.strip() or None,
                                   origin=self.origin)
        made = []

        def new_scene():  # called once the network is read and planned
            made.append(bpy.data.scenes.new(scene_name_for(path)))
            return BlenderRoadScene(made[0])

        def say(text):
            status_text(context, f"SUMO network: {text}")

        try:
            info = scene_from_net(settings, new_scene, say)
        except RLSError as exc:
            for scene in made:
                bpy.data.scenes.remove(scene)
            return cancelled(self, exc)
        finally:
            status_text(context, None)
        if context.window is not None:
            context.window.scene = made[0]
        self.report({"INFO"}, f"Scene '{made[0].name}': junction {info['junction']}, "
                              f"{len(info['mounts'])} mounts, {info['triangles']} triangles")
        return {"FINISHED"}


def draw_import_menu(self, context):
    self.layout.operator(RLS_OT_import_sumo_network.bl_idname,
                         text="SUMO Network as Scene (.net.xml)")


CLASSES = (RLS_OT_import_sumo_network,)

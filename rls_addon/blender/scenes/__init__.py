"""Sample scenes built with ``bpy.data`` (see ``build.py`` for the conventions).

``SCENES`` maps a scene id to its builder; ``SUMO_SCENES`` those whose traffic SUMO
makes (they need the eclipse-sumo wheel or SUMO_HOME); ``build_scene(name, scene)``
empties nothing, it fills the given (empty) scene and returns the builder's dict.
``SAMPLE_LIDARS`` is the LiDAR each scene file ships with (``add_sample_lidar``, called
by ``sample_scenes/make_scenes.py`` and ``rls demo``), named as the README's examples
use it; ``build_scene`` adds none, so tests choose their own.
"""

from ...core.scene.mounting import LidarMounting
from .streets import build_four_lane, build_intersection, build_t_junction

SCENES = {
    "t_junction": build_t_junction,
    "intersection": build_intersection,
    "four_lane": build_four_lane,
}


def _intersection_sumo(scene):
    from .sumo_intersection import build_intersection_sumo

    return build_intersection_sumo(scene)


SUMO_SCENES = {"intersection_sumo": _intersection_sumo}


def build_scene(name, scene):
    try:
        builder = SCENES.get(name) or SUMO_SCENES[name]
    except KeyError:
        from ...core.errors import SceneError

        raise SceneError(f"unknown sample scene {name!r}; choose one of {', '.join([*SCENES, *SUMO_SCENES])}") from None
    scene.name = name
    return builder(scene)


# A Pandar64 on a corner pole (a street light on the four-lane road) 12 degrees nose
# down, facing the middle of the region: the junction's far side falls within its upper
# beams (``rls demo``'s sensor).
_CORNER = LidarMounting(preset="hesai_pandar64", name="LiDAR", mount="TL SW", pitch_deg=12.0,
                        face_region=True)
SAMPLE_LIDARS = {
    "t_junction": _CORNER,
    "intersection": _CORNER,
    "intersection_sumo": _CORNER,
    "four_lane": LidarMounting(preset="hesai_pandar64", name="LiDAR", mount="SL S +0",
                               pitch_deg=12.0, face_region=True),
}


def add_sample_lidar(name, scene, preset=None):
    """Add sample scene ``name``'s LiDAR (``SAMPLE_LIDARS``) to ``scene``, of device
    ``preset`` when given; returns the object."""
    import dataclasses

    from ..lidars import add_lidar

    mounting = SAMPLE_LIDARS[name]
    if preset is not None:
        mounting = dataclasses.replace(mounting, preset=preset)
    return add_lidar(scene, mounting)

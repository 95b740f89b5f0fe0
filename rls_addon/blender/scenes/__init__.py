"""Sample scenes built with ``bpy.data`` (see ``build.py`` for the conventions).

``SCENES`` maps a scene id to its builder; ``SUMO_SCENES`` those whose traffic SUMO
makes (they need the eclipse-sumo wheel or SUMO_HOME); ``build_scene(name, scene)``
empties nothing, it fills the given (empty) scene and returns the builder's dict.
"""

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

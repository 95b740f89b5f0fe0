"""Sample scenes built with ``bpy.data`` (see ``build.py`` for the conventions).

``SCENES`` maps a scene id to its builder; ``build_scene(name, scene)`` empties
nothing, it fills the given (empty) scene and returns the builder's dict.
"""

from .streets import build_four_lane, build_intersection, build_t_junction

SCENES = {
    "t_junction": build_t_junction,
    "intersection": build_intersection,
    "four_lane": build_four_lane,
}


def build_scene(name, scene):
    try:
        builder = SCENES[name]
    except KeyError:
        from ...core.errors import SceneError

        raise SceneError(f"unknown sample scene {name!r}; choose one of {', '.join(SCENES)}") from None
    scene.name = name
    return builder(scene)

"""What the core asks of a scene: the interface a scene source implements.

The core owns the scan: which objects move and how (``sweep``), what is prepared and
kept (``session``), frames x sensors, seeds, files, resume, cancel and progress
(``run``). A *scene source* only answers questions about one scene at one time. The
Blender layer's source (``blender.source.BlenderScene``) answers them from a
depsgraph; core tests answer them with small fakes, in milliseconds.

A placement study asks its own questions (``StudyScene``: the region, the mounts, the
static geometry without traffic, the traffic at chosen frames); the Blender layer's
``blender.study.BlenderStudyScene`` answers them.
"""

from dataclasses import dataclass, field
from typing import Protocol

import numpy as np

from .instances import Instance


@dataclass
class SceneRead:
    """Everything within reach of a sensor at the current frame."""

    instances: list           # [Instance]
    materials: list           # [MaterialInfo], shared by every instance
    stats: dict = field(default_factory=dict)  # objects, culled_by_range, hidden
    # what a scan of this read should say of it (objects a render shows that the source
    # could not read), in the source's own words
    warnings: list = field(default_factory=list)


@dataclass
class Mobility:
    """Which of a read's instances can change over time (animation, constraints,
    physics, modifiers ...), and whether the sensor can. Objects that cannot change are
    never sampled."""

    candidates: list = field(default_factory=list)  # indices into SceneRead.instances
    deformable: set = field(default_factory=set)    # keys of those whose mesh may change
    sensor_moves: bool = False


class Sweep(Protocol):
    """The scene over one sweep of one frame: states at times ``t`` in seconds since the
    sweep start. Used as a context manager: leaving it puts the scene back at the
    frame."""

    def state(self, t: float, keys: set, deform_keys: set,
              sensor: str) -> tuple[dict, dict, np.ndarray | None]:
        """({key: 4x4 world matrix} of ``keys``, {key: local vertices} of
        ``deform_keys``, the sensor's 4x4 world matrix or None)."""

    def instance_at(self, t: float, instance: Instance) -> Instance | None:
        """``instance`` as it is at ``t`` (a deforming object's mesh and matrix), or
        None when it is gone."""

    def __enter__(self): ...

    def __exit__(self, *exc): ...


class SceneSource(Protocol):
    """A scene the core can scan (see the module docstring)."""

    name: str           # the scene's name (used in file names)
    fps: float          # frames per second of the scene's animation
    frame_start: int    # the scene's first frame (time 0 of its timestamps)

    def current_frame(self) -> int: ...

    def set_frame(self, frame: int) -> None: ...

    def sensor_pose(self, sensor: str) -> np.ndarray:
        """The sensor's 4x4 world matrix at the current frame."""

    def sensor_may_move(self, sensor: str) -> bool:
        """Whether anything could move the sensor over time (it is animated)."""

    def read(self, centre: np.ndarray, max_range: float, exclude: set) -> SceneRead:
        """Instances within ``max_range`` of ``centre`` at the current frame, but the
        objects named in ``exclude`` (the sensor itself)."""

    def mobility(self, instances: list, sensor: str) -> Mobility: ...

    def sweep(self, frame: int, period: float) -> Sweep: ...

    # May offer ``traffic_span() -> (first, last) | None``: the frames over which its
    # road users are keyed (``traffic_keys``); frames outside are refused.


class StudyScene(Protocol):
    """What a study asks of a scene."""

    name: str
    file: str           # optional: its file's name (what charts call it); default ``name``

    def current_frame(self) -> int: ...

    def set_frame(self, frame: int) -> None: ...

    def region(self, name: str | None) -> np.ndarray:
        """(N, 2) world xy outline of the InfraLOB ``name`` (None: the one marked)."""

    def mounts(self, names: tuple) -> list:
        """[(name, (x, y, z))] of the mounts ``names`` (empty: every marked mount)."""

    def static_geometry(self, hidden_labels: set) -> tuple:
        """(SceneGeometry of everything rendered but objects with these label ids,
        sorted names of the objects left out). A scene that could not read all that
        a render shows may say so in a list ``warnings`` of its own (the study's
        notices)."""

    def traffic(self, frames: tuple, labels: set) -> dict:
        """{frame: source.SceneRead} of the objects with these label ids at each frame
        (their meshes in their own frames, their matrices at that frame)."""

    # May offer ``traffic_span()``, as a ``SceneSource`` may.

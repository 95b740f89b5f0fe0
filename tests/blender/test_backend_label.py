"""The Motion panel says, under the backend choice, which backend that LiDAR will use
here and why (``casting.backend_status``), and redrawing it costs no backend work."""

from types import SimpleNamespace

from rls_addon.core import casting

from .conftest import add_lidar
from .test_ui_panels import _draw


def _status_labels(obj, scene):
    from rls_addon import ui

    ctx = SimpleNamespace(object=obj, active_object=obj, scene=scene)
    log = _draw(ui.OBJECT_PT_rls_lidar_motion, ctx)
    names = [(name, a[1] if name == "prop" else kw.get("text")) for name, a, kw in log]
    at = names.index(("prop", "backend"))
    assert names[at + 1][0] == "label", names  # the line right under the choice
    return names[at + 1][1]


def test_label_under_backend_says_what_each_choice_resolves_to(scene, monkeypatch):
    obj = add_lidar()
    casting.backend_status.cache_clear()
    for choice in ("auto", "bvhtree", "embree"):
        obj.rls_lidar.backend = choice
        text = _status_labels(obj, scene)
        assert text == casting.backend_status(choice)[1]
        factory, _ = casting.caster_factory(choice)
        assert casting.backend_status(choice)[0] == factory.name
    obj.rls_lidar.backend = "bvhtree"
    assert _status_labels(obj, scene) == "BVHTree: as chosen (one core)"

    def explode(*a, **k):
        raise AssertionError("draw() worked out the backend again")

    # Redraws read the cached answer: no import, no library loading, no files.
    monkeypatch.setattr(casting, "caster_factory", explode)
    for choice in ("auto", "bvhtree", "embree"):
        obj.rls_lidar.backend = choice
        assert _status_labels(obj, scene) == casting.backend_status(choice)[1]
    casting.backend_status.cache_clear()

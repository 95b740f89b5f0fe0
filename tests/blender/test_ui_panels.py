"""Panels and menus: every ``draw()`` runs against a recording layout with the disk,
preset loading, scanning and metrics made to fail, so drawing provably does no heavy
work; every property and operator a panel names exists."""

import builtins
from types import SimpleNamespace

import pytest

from .conftest import bpy
from .ops_helpers import add_lidar_op, labelled_ground, user_dir  # noqa: F401 (fixture)


class Recorder:
    """Stands in for ``UILayout``: records calls, checks names against RNA. Layout
    panels (``layout.panel``) are closed unless ``open_panels``."""

    def __init__(self, log, open_panels=False):
        object.__setattr__(self, "log", log)
        object.__setattr__(self, "open_panels", open_panels)

    def __getattr__(self, name):
        def call(*args, **kw):
            self.log.append((name, args, kw))
            if name == "panel":
                return (Recorder(self.log, self.open_panels),
                        Recorder(self.log, self.open_panels) if self.open_panels else None)
            if name == "prop":
                data, prop = args[0], args[1]
                assert prop in data.bl_rna.properties, f"{type(data).__name__} has no {prop}"
            if name == "operator":
                mod, _, op = args[0].partition(".")
                getattr(getattr(bpy.ops, mod), op).get_rna_type()  # raises if unknown
                return SimpleNamespace()
            if name in ("menu", "popover"):
                ident = args[0] if args else kw.get("panel") or kw.get("menu")
                assert hasattr(bpy.types, ident), ident
            if name == "icon":
                return 0
            return Recorder(self.log, self.open_panels)
        return call


def _draw(cls, context, method="draw", open_panels=False):
    log = []
    getattr(cls, method)(SimpleNamespace(layout=Recorder(log, open_panels),
                                         bl_idname=getattr(cls, "bl_idname", "")), context)
    return log


def _explode(*a, **k):
    raise AssertionError("draw() did heavy work")


@pytest.fixture
def no_heavy_work(monkeypatch):
    """Patch the disk and the expensive calls so any use from draw() fails the test."""
    import rls_addon.core.scan.session as scan
    import rls_addon.core.metrics.infra as metrics
    import rls_addon.core.device.presets as presets
    from rls_addon.blender import preset_catalog

    preset_catalog.catalog()  # the cached catalog is what draw() may use

    def guard():
        monkeypatch.setattr(presets, "load_preset", _explode)
        monkeypatch.setattr(preset_catalog, "builtin_presets", _explode)
        monkeypatch.setattr(preset_catalog, "refresh", _explode)
        monkeypatch.setattr(preset_catalog, "resolve", _explode)
        monkeypatch.setattr(scan.ScanSession, "scan", _explode)
        monkeypatch.setattr(metrics, "infra_lob_metrics", _explode)
        monkeypatch.setattr(builtins, "open", _explode)

    return guard


def _ui_classes():
    from rls_addon import ui

    return ui


def test_lidar_panels_draw_without_heavy_work(scene, user_dir, no_heavy_work):
    ui = _ui_classes()
    labelled_ground()
    obj = add_lidar_op("livox_avia")
    assert bpy.ops.rls.scan_frame(write=False) == {"FINISHED"}
    bpy.ops.object.rls_add_infralob()
    scene.rls.metric_disks = 200
    assert bpy.ops.rls.compute_metrics() == {"FINISHED"}
    ctx = SimpleNamespace(object=obj, active_object=obj, scene=scene)
    no_heavy_work()
    panels = [ui.OBJECT_PT_rls_lidar, ui.OBJECT_PT_rls_lidar_range, ui.OBJECT_PT_rls_lidar_motion,
              ui.OBJECT_PT_rls_lidar_output, ui.OBJECT_PT_rls_lidar_preview,
              ui.OBJECT_PT_rls_lidar_metrics, ui.RLS_PT_device_presets]
    logs = {}
    for cls in panels:
        if hasattr(cls, "poll"):
            assert cls.poll(ctx), cls.__name__
        logs[cls.__name__] = _draw(cls, ctx)
    header = _draw(ui.OBJECT_PT_rls_lidar, ctx, "draw_header_preset")
    assert header[0][0] == "popover" and header[0][2]["panel"] == "RLS_PT_device_presets"
    assert header[0][2]["text"] == "Livox Avia"
    main = logs["OBJECT_PT_rls_lidar"]
    labels = " ".join(kw.get("text", "") for name, _, kw in main if name == "label")
    assert "Source:" in labels and "Risley, built-in" in labels
    props = {a[1] for log in logs.values() for name, a, _ in log if name == "prop"}
    for p in ("preset", "min_range", "max_range", "noise_sigma", "noise", "dropout", "seed",
              "motion", "substeps", "ghosting", "output_dir", "file_format", "fields",
              "frame_space", "name_template", "preview_color", "show_fov",
              "use_rotation_hz", "rotation_hz"):
        assert p in props, p
    ops = [a[0] for log in logs.values() for name, a, _ in log if name == "operator"]
    for op in ("rls.scan_frame", "rls.scan_all", "rls.scan_range", "rls.preview_color",
               "rls.compute_metrics", "rls.preset_apply", "rls.preset_save",
               "rls.preset_import", "rls.preset_import_calibration", "rls.preset_export",
               "rls.preset_refresh"):
        assert op in ops, op
    metrics_labels = [kw.get("text", "") for name, _, kw in logs["OBJECT_PT_rls_lidar_metrics"]
                      if name == "label"]
    assert "InfraD" in metrics_labels and "InfraNUC" in metrics_labels
    assert any(name == "template_icon" for name, _, _ in logs["OBJECT_PT_rls_lidar_metrics"])


def test_preset_source_folds_to_one_line(scene):
    """The device's source text (30 lines for a Pandar64) once filled the LiDAR panel:
    folded it is one line, open the whole text."""
    ui = _ui_classes()
    obj = add_lidar_op("hesai_pandar64")
    ctx = SimpleNamespace(object=obj, active_object=obj, scene=scene)

    def labels(log):
        return [kw.get("text", "") for name, _, kw in log if name == "label"]

    folded, opened = (labels(_draw(ui.OBJECT_PT_rls_lidar, ctx, open_panels=o))
                      for o in (False, True))
    from rls_addon.blender import preset_catalog

    source = preset_catalog.entry("hesai_pandar64").source
    assert len(opened) - len(folded) >= 25  # the text, wrapped
    assert [t for t in folded if t.startswith("Source:")] == [f"Source: {source[:40].rstrip()}..."]
    assert " ".join(opened).count(source.split()[-1]) >= 1  # its end shows when open
    assert len(folded) <= 3


def test_panels_use_property_split():
    import inspect

    ui = _ui_classes()
    for cls in (ui.OBJECT_PT_rls_lidar, ui.OBJECT_PT_rls_lidar_range, ui.OBJECT_PT_rls_lidar_motion,
                ui.OBJECT_PT_rls_lidar_output, ui.OBJECT_PT_rls_lidar_preview, ui.OBJECT_PT_rls_label):
        assert "use_property_split = True" in inspect.getsource(cls.draw), cls.__name__


def test_add_menu_groups_presets_by_family(scene, user_dir, no_heavy_work):
    from rls_addon.blender import preset_catalog

    ui = _ui_classes()
    add_lidar_op("velodyne_vlp16")
    assert bpy.ops.rls.preset_save(name="Team Sensor") == {"FINISHED"}  # a user preset
    ctx = SimpleNamespace(object=None, active_object=None, scene=scene)
    no_heavy_work()
    top = _draw(ui.VIEW3D_MT_rls_add, ctx)
    menus = [a[0] for name, a, _ in top if name == "menu"]
    assert menus == ["VIEW3D_MT_rls_add_spinning", "VIEW3D_MT_rls_add_mems", "VIEW3D_MT_rls_add_risley"]
    assert ("object.rls_add_infralob",) in [a for name, a, _ in top if name == "operator"]
    listed = {}
    for menu in ui.family_menus():
        log = _draw(menu, ctx)
        listed[menu.bl_idname.rsplit("_", 1)[1]] = [kw.get("text") for n, _, kw in log if n == "operator"]
    by_family = {f.id: [e.name for e in es] for f, es in preset_catalog.by_family()}
    assert listed["spinning"] == by_family["spinning"] and "Team Sensor" in listed["spinning"]
    assert "Velodyne VLP-16" in listed["spinning"] and "Livox Mid-40" in listed["risley"]
    assert listed["custom"] == []
    add = _draw(SimpleNamespace(draw=ui.draw_add_menu), ctx)
    assert add[0][1] == ("VIEW3D_MT_rls_add",)


def test_label_panel_edits_rls_label(scene):
    ui = _ui_classes()
    g = labelled_ground(label="sidewalk")
    ctx = SimpleNamespace(object=g, active_object=g, scene=scene)
    assert ui.OBJECT_PT_rls_label.poll(ctx)
    assert g.rls_lidar.label == "SIDEWALK"
    g.rls_lidar.label = "VEGETATION"
    assert g["rls_label"] == "vegetation"
    g.rls_lidar.label = "NONE"
    assert "rls_label" not in g
    g["rls_label"] = 11  # an id set by a script shows too
    assert g.rls_lidar.label == "VEHICLE"
    _draw(ui.OBJECT_PT_rls_label, ctx)
    lidar = add_lidar_op()
    assert not ui.OBJECT_PT_rls_label.poll(SimpleNamespace(object=lidar))


def test_infralob_panel_only_for_regions(scene):
    ui = _ui_classes()
    bpy.ops.object.rls_add_infralob()
    lob = bpy.context.active_object
    assert ui.OBJECT_PT_rls_infralob.poll(SimpleNamespace(object=lob))
    assert not ui.OBJECT_PT_rls_lidar.poll(SimpleNamespace(object=lob))
    assert not ui.OBJECT_PT_rls_label.poll(SimpleNamespace(object=lob))
    log = _draw(ui.OBJECT_PT_rls_infralob, SimpleNamespace(object=lob, active_object=lob, scene=scene))
    assert ("rls.compute_metrics",) in [a for n, a, _ in log if n == "operator"]

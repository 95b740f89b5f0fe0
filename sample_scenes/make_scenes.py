"""Write the paper's three placement scenes as .blend files.

    .venv/bin/python sample_scenes/make_scenes.py [--out DIR] [NAME ...]

NAME is t_junction, intersection, four_lane or intersection_sumo (default: all four);
DIR defaults to this folder. intersection_sumo is scene B with its traffic made by SUMO
(a fixed seed); without SUMO (pip install eclipse-sumo sumolib) it is skipped with a
note and the others are still written. The scenes are built by ``rls_addon.blender.scenes`` with ``bpy.data``
only, so the same code runs in the ``bpy`` module, ``blender -b`` and the UI.
"""

import argparse
import os
import sys

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, os.path.dirname(HERE))


def main(argv=None):
    import bpy

    from rls_addon.blender.quiet import blender_output_silenced
    from rls_addon.blender.scenes import SCENES, SUMO_SCENES, build_scene
    from rls_addon.core.traffic.sumo_run import SumoMissing

    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("names", nargs="*", choices=[[], *SCENES, *SUMO_SCENES], default=[],
                   metavar="NAME")
    p.add_argument("--out", default=HERE)
    args = p.parse_args(argv)
    os.makedirs(args.out, exist_ok=True)
    for name in args.names or [*SCENES, *SUMO_SCENES]:
        bpy.ops.wm.read_factory_settings(use_empty=True)
        try:
            info = build_scene(name, bpy.context.scene)
        except SumoMissing as exc:
            print(f"{name}: skipped: {exc}", file=sys.stderr)
            continue
        path = os.path.abspath(os.path.join(args.out, f"{name}.blend"))
        tmp = path + ".tmp.blend"
        with blender_output_silenced():
            bpy.ops.wm.save_as_mainfile(filepath=tmp, compress=True)
        os.replace(tmp, path)
        print(f"{path}: region {info['infralob']}, {len(info['mounts'])} mounts "
              f"({', '.join(info['mounts'])}), {len(info['vehicles'])} vehicles "
              f"({len(info['parked'])} parked), {len(info['pedestrians'])} pedestrians, "
              f"{len(info['cyclists'])} cyclists")
    return 0


if __name__ == "__main__":
    sys.exit(main())

"""Write the paper's three placement scenes as .blend files.

    .venv/bin/python sample_scenes/make_scenes.py [--out DIR] [NAME ...]

NAME is t_junction, intersection, four_lane or intersection_sumo (default: all four);
DIR defaults to this folder. Each scene ships with a Pandar64 named ``LiDAR`` on a corner
pole, facing the region (``rls lidar list FILE`` shows it). intersection_sumo is scene B with its traffic made by SUMO
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

    import rls_addon
    from rls_addon.blender.files import save_blend
    from rls_addon.blender.scenes import (SAMPLE_LIDARS, SCENES, SUMO_SCENES, add_sample_lidar,
                                          build_scene)
    from rls_addon.core.traffic.sumo_run import SumoMissing

    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("names", nargs="*", choices=[[], *SCENES, *SUMO_SCENES], default=[],
                   metavar="NAME")
    p.add_argument("--out", default=HERE)
    args = p.parse_args(argv)
    os.makedirs(args.out, exist_ok=True)
    for name in args.names or [*SCENES, *SUMO_SCENES]:
        bpy.ops.wm.read_factory_settings(use_empty=True)
        rls_addon.ensure_registered()  # the factory settings dropped RLS's properties
        try:
            info = build_scene(name, bpy.context.scene)
        except SumoMissing as exc:
            print(f"{name}: skipped: {exc}", file=sys.stderr)
            continue
        lidar = add_sample_lidar(name, bpy.context.scene)
        path = save_blend(os.path.join(args.out, f"{name}.blend"), overwrite=True)
        print(f"{path}: LiDAR '{lidar.name}' ({lidar.rls_lidar.preset_id}) on "
              f"'{SAMPLE_LIDARS[name].mount}', region {info['infralob']}, {len(info['mounts'])} mounts "
              f"({', '.join(info['mounts'])}), {len(info['vehicles'])} vehicles "
              f"({len(info['parked'])} parked), {len(info['pedestrians'])} pedestrians, "
              f"{len(info['cyclists'])} cyclists")
    return 0


if __name__ == "__main__":
    sys.exit(main())

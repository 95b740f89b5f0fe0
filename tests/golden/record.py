"""Golden checksums: the bytes RLS writes for fixed scenes, seeds and settings.

Recorded before the scan run moved into the core (issue: one scan run behind every
entry point) and compared after every change since: a refactoring must not change
one byte of a cloud. Run as a script to print the current checksums:

    .venv/bin/python tests/golden/record.py            # print
    .venv/bin/python tests/golden/record.py --write    # replace checksums.json

Only clouds and study tables are hashed: sidecars carry run-dependent values
(timings, software version) and grow new keys.
"""

import hashlib
import json
import sys
from pathlib import Path


ROOT = Path(__file__).resolve().parents[2]
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))

CHECKSUMS = Path(__file__).with_name("checksums.json")


def sha(data):
    return hashlib.sha256(bytes(data)).hexdigest()[:16]


# ---- core: numpy caster, no Blender ----------------------------------------------------

def core_cases():
    from rls_addon.core.output.io import encode_cloud
    from tests.golden.scenes import core_scan

    out = {}
    for mode, sub in (("exact", 0), ("snapshot", 0), ("substeps", 4)):
        for space in ("sensor", "world"):
            pts = core_scan(mode, sub, space)
            out[f"core/{mode}{sub or ''}/{space}"] = sha(encode_cloud(pts, "pcd_binary"))
    return out


def effect_cases():
    """Frames with the LiDAR equation, footprints and weather (``scenes.effect_scan``)."""
    from rls_addon.core.output.io import encode_cloud
    from tests.golden.scenes import EFFECT_CASES, effect_scan

    out = {}
    for case in EFFECT_CASES:
        for space in ("sensor", "world"):
            pts = effect_scan(case, space)
            out[f"effects/{case}/{space}"] = sha(encode_cloud(pts, "pcd_binary"))
    return out


# ---- Blender: the demo street through a scan session --------------------------------------

def blender_cases():

    from rls_addon.core.output.io import encode_cloud
    from tests.golden.scenes import blender_street_scans

    out = {}
    for name, pts in blender_street_scans():
        out[f"blender/{name}/pcd_binary"] = sha(encode_cloud(pts, "pcd_binary"))
        out[f"blender/{name}/ply_binary_range"] = sha(encode_cloud(
            pts, "ply_binary", fields=("x", "y", "z", "intensity", "range", "ring", "time")))
    return out


def study_cases():
    from tests.golden.scenes import junction_study

    out = {}
    rows, best = junction_study()
    out["study/t_junction/candidates"] = sha(json.dumps(rows, sort_keys=True).encode())
    out["study/t_junction/best"] = sha(json.dumps(best, sort_keys=True).encode())
    return out


def compute():
    got = {}
    got.update(core_cases())
    got.update(effect_cases())
    got.update(blender_cases())
    got.update(study_cases())
    return got


if __name__ == "__main__":
    got = compute()
    print(json.dumps(got, indent=2, sort_keys=True))
    if "--write" in sys.argv:
        CHECKSUMS.write_text(json.dumps(got, indent=2, sort_keys=True) + "\n")

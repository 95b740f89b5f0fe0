"""Golden checksums: the bytes RLS writes for fixed scenes, seeds and settings.

Recorded before the scan run moved into the core (issue: one scan run behind every
entry point) and compared after every change since: a refactoring must not change
one byte of a cloud. Run as a script to see what changed against the record:

    .venv/bin/python tests/golden/record.py            # print the changes, write nothing
    .venv/bin/python tests/golden/record.py --write    # print them, then record the outputs

Both print, for every case whose bytes changed, what changed in it: the number of
points (or table rows) and each field that differs, with its minimum, mean and
maximum before and after (``summaries.json`` keeps them beside the checksums), so that
a deliberate change is reviewed case by case, not re-recorded blind. Say in the commit
that records new checksums which cases changed and why.

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
SUMMARIES = Path(__file__).with_name("summaries.json")


def sha(data):
    return hashlib.sha256(bytes(data)).hexdigest()[:16]


# ---- what a case holds, for the report of changes ------------------------------------------

def _column(values):
    """A field's digest and, for numbers, its minimum, mean and maximum."""
    import numpy as np

    values = np.asarray(values)
    out = {"sha": sha(np.ascontiguousarray(values).tobytes() if values.dtype != object
                      else json.dumps(values.tolist()).encode())}
    if len(values) and values.dtype.kind in "iufb":
        f = values.astype(np.float64)
        out.update(min=float(f.min()), mean=float(f.mean()), max=float(f.max()))
    return out


def cloud_summary(points):
    """{"points": N, "fields": {name: column summary}} of a point record array."""
    return {"points": int(len(points)),
            "fields": {name: _column(points[name]) for name in points.dtype.names}}


def table_summary(rows, columns):
    """The same for a table (a list of rows, one value per column): "rows" for points."""
    import numpy as np

    fields = {}
    for j, name in enumerate(columns):
        values = [r[j] for r in rows]
        try:
            arr = np.array([float(v) for v in values])
        except (TypeError, ValueError):
            arr = np.array(values, dtype=object)
        fields[name] = _column(arr)
    return {"rows": len(rows), "fields": fields}


def _fmt(v):
    return f"{v:.9g}"


def describe(case, old, new):
    """One line saying how case ``case`` changed from summary ``old`` to ``new``."""
    if old is None:
        return f"{case}: no summary recorded (recorded before summaries.json)"
    parts = []
    for unit in ("points", "rows"):
        if unit in old or unit in new:
            a, b = old.get(unit), new.get(unit)
            parts.append(f"{unit} {a} -> {b}" + (f" ({b - a:+d})" if a is not None
                                                  and b is not None and a != b else ""))
    fo, fn = old.get("fields", {}), new.get("fields", {})
    gone, added = sorted(set(fo) - set(fn)), sorted(set(fn) - set(fo))
    if gone:
        parts.append("fields removed: " + ", ".join(gone))
    if added:
        parts.append("fields added: " + ", ".join(added))
    resized = old.get("points", old.get("rows")) != new.get("points", new.get("rows"))
    changed = 0
    for f in (f for f in fn if f in fo and fn[f]["sha"] != fo[f]["sha"]):
        stats = [f"{k} {_fmt(fo[f][k])} -> {_fmt(fn[f][k])}" for k in ("min", "mean", "max")
                 if k in fo[f] and k in fn[f] and fo[f][k] != fn[f][k]]
        if stats:
            parts.append(f"{f} changed ({', '.join(stats)})")
        elif not resized or "min" not in fn[f]:
            parts.append(f"{f} changed" + (" (same min, mean, max)" if "min" in fn[f] else ""))
        else:
            continue  # as many values fewer or more, with the same range: the count says it
        changed += 1
    if not changed and not gone and not added and not resized:
        parts.append("same values, other bytes (order or encoding)")
    return f"{case}: " + "; ".join(parts)


def changes(want, got, want_summaries, got_summaries):
    """Lines naming every case added, removed or changed, and how."""
    lines = [f"{case}: new case" for case in sorted(set(got) - set(want))]
    lines += [f"{case}: removed" for case in sorted(set(want) - set(got))]
    lines += [describe(case, want_summaries.get(case), got_summaries.get(case))
              for case in sorted(set(want) & set(got)) if want[case] != got[case]]
    return lines


# ---- core: numpy caster, no Blender ----------------------------------------------------

def core_cases(summaries):
    from rls_addon.core.output.io import encode_cloud
    from tests.golden.scenes import core_scan

    out = {}
    for mode, sub in (("exact", 0), ("snapshot", 0), ("substeps", 4)):
        for space in ("sensor", "world"):
            pts = core_scan(mode, sub, space)
            key = f"core/{mode}{sub or ''}/{space}"
            out[key] = sha(encode_cloud(pts, "pcd_binary"))
            summaries[key] = cloud_summary(pts)
    return out


def effect_cases(summaries):
    """Frames with the LiDAR equation, footprints and weather (``scenes.effect_scan``)."""
    from rls_addon.core.output.io import encode_cloud
    from tests.golden.scenes import EFFECT_CASES, effect_scan

    out = {}
    for case in EFFECT_CASES:
        for space in ("sensor", "world"):
            pts = effect_scan(case, space)
            key = f"effects/{case}/{space}"
            out[key] = sha(encode_cloud(pts, "pcd_binary"))
            summaries[key] = cloud_summary(pts)
    return out


# ---- Blender: the demo street through a scan session --------------------------------------

PLY_FIELDS = ("x", "y", "z", "intensity", "range", "ring", "time")


def blender_cases(summaries):

    from rls_addon.core.output.io import encode_cloud
    from tests.golden.scenes import blender_street_scans

    out = {}
    for name, pts in blender_street_scans():
        out[f"blender/{name}/pcd_binary"] = sha(encode_cloud(pts, "pcd_binary"))
        out[f"blender/{name}/ply_binary_range"] = sha(encode_cloud(
            pts, "ply_binary", fields=PLY_FIELDS))
        summaries[f"blender/{name}/pcd_binary"] = cloud_summary(pts)
        summaries[f"blender/{name}/ply_binary_range"] = cloud_summary(pts)
    return out


STUDY_COLUMNS = ("candidate", "n_points", "scan_points", "infra_d", "infra_nuc")
BEST_COLUMNS = ("k", "members", "infra_d", "infra_nuc", "front")


def study_cases(summaries):
    from tests.golden.scenes import junction_study

    out = {}
    rows, best = junction_study()
    out["study/t_junction/candidates"] = sha(json.dumps(rows, sort_keys=True).encode())
    out["study/t_junction/best"] = sha(json.dumps(best, sort_keys=True).encode())
    summaries["study/t_junction/candidates"] = table_summary(rows, STUDY_COLUMNS)
    summaries["study/t_junction/best"] = table_summary(
        [[k, json.dumps(v[0]), *v[1:]] for k, v in sorted(best.items())], BEST_COLUMNS)
    return out


def compute(summaries=None):
    """{case: checksum}; ``summaries``, a dict, receives each case's summary."""
    summaries = {} if summaries is None else summaries
    got = {}
    got.update(core_cases(summaries))
    got.update(effect_cases(summaries))
    got.update(blender_cases(summaries))
    got.update(study_cases(summaries))
    return got


def _read(path):
    return json.loads(path.read_text()) if path.is_file() else {}


def main(argv, run=compute, checksums=CHECKSUMS, summaries_path=SUMMARIES, out=sys.stdout):
    """Print what changed against the record; with ``--write`` record the outputs."""
    want, want_summaries = _read(checksums), _read(summaries_path)
    got_summaries = {}
    got = run(got_summaries)
    lines = changes(want, got, want_summaries, got_summaries)
    if lines:
        print(f"golden cases that differ from the record ({len(lines)}; {len(got)} cases now):",
              file=out)
        for line in lines:
            print("  " + line, file=out)
    else:
        print(f"all {len(got)} golden cases match the record", file=out)
    if "--write" in argv:
        checksums.write_text(json.dumps(got, indent=2, sort_keys=True) + "\n")
        summaries_path.write_text(json.dumps(got_summaries, indent=1, sort_keys=True) + "\n")
        print(f"recorded {checksums.name} and {summaries_path.name}: say in the commit which "
              f"cases changed and why", file=out)
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))

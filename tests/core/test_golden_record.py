"""``tests/golden/record.py`` reports which golden cases changed and how (points,
fields, their ranges) before it records anything, so that a deliberate change is
reviewed case by case; ``--write`` then records checksums and summaries."""

import io
import json

import numpy as np

from rls_addon.core.output.io import encode_cloud
from rls_addon.core.points import empty_points
from tests.golden import record


def cloud(n, shift=0.0):
    pts = empty_points(n)
    pts["x"] = np.arange(n) + shift
    pts["y"] = 2.0
    pts["intensity"] = 0.5
    pts["label"] = 1
    return pts


def fake_run(clouds):
    def run(summaries):
        out = {}
        for case, pts in clouds.items():
            out[case] = record.sha(encode_cloud(pts, "pcd_binary"))
            summaries[case] = record.cloud_summary(pts)
        return out
    return run


def main(argv, clouds, tmp_path):
    text = io.StringIO()
    record.main(argv, fake_run(clouds), tmp_path / "checksums.json", tmp_path / "summaries.json",
                text)
    return text.getvalue()


def test_a_change_is_reported_with_its_points_and_fields(tmp_path):
    before = {"a": cloud(10), "b": cloud(5), "gone": cloud(3)}
    main(["--write"], before, tmp_path)
    recorded = json.loads((tmp_path / "checksums.json").read_text())
    assert sorted(recorded) == ["a", "b", "gone"]
    assert "all 3 golden cases match" in main([], before, tmp_path)

    after = {"a": cloud(9), "b": cloud(5, shift=0.25), "new": cloud(2)}
    report = main([], after, tmp_path)
    assert "differ from the record (4; 3 cases now)" in report
    assert "new: new case" in report and "gone: removed" in report
    line_a = next(x for x in report.splitlines() if x.strip().startswith("a:"))
    assert "points 10 -> 9 (-1)" in line_a and "x changed (mean 4.5 -> 4, max 9 -> 8)" in line_a
    # one point fewer of the same y, intensity, ...: the count says it, no field listed
    assert line_a.count("changed") == 1
    line_b = next(x for x in report.splitlines() if x.strip().startswith("b:"))
    assert "points 5 -> 5" in line_b and "(min 0 -> 0.25, mean 2 -> 2.25, max 4 -> 4.25)" in line_b
    # nothing written without --write
    assert json.loads((tmp_path / "checksums.json").read_text()) == recorded
    main(["--write"], after, tmp_path)
    assert sorted(json.loads((tmp_path / "checksums.json").read_text())) == ["a", "b", "new"]
    assert json.loads((tmp_path / "summaries.json").read_text())["a"]["points"] == 9


def test_study_tables_report_rows_and_columns():
    old = record.table_summary([["TL NE", 10, 20, "1.5", "0.25"]], record.STUDY_COLUMNS)
    new = record.table_summary([["TL NE", 10, 20, "1.75", "0.25"], ["SL S", 3, 4, "0.5", "0.1"]],
                               record.STUDY_COLUMNS)
    line = record.describe("study/x", old, new)
    assert "rows 1 -> 2 (+1)" in line and "candidate changed" in line
    assert "infra_d changed (min 1.5 -> 0.5, mean 1.5 -> 1.125, max 1.5 -> 1.75)" in line

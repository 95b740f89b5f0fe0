"""No Python file of the package is over 500 lines (a room that grows past it is split
by concern, with names that say what each part holds: docs/architecture.md)."""

from pathlib import Path

PACKAGE = Path(__file__).resolve().parents[2] / "rls_addon"
LIMIT = 500


def test_no_python_file_over_500_lines():
    over = {str(p.relative_to(PACKAGE.parent)): n for p in sorted(PACKAGE.rglob("*.py"))
            if (n := len(p.read_text().splitlines())) > LIMIT}
    assert not over, f"over {LIMIT} lines: {over}"

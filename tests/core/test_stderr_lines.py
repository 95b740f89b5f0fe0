"""The command line's stderr lines are written whole: one write per line, so a stop
signal handled between two writes can never leave a progress line open for the
"rls: interrupted" line to land on (seen under load in the random-SIGTERM test)."""

import ast
from pathlib import Path

from rls_addon.commands.stderr import say

ROOT = Path(__file__).resolve().parents[2] / "rls_addon"


def test_say_writes_a_line_in_one_write(monkeypatch):
    writes = []

    class Err:
        def write(self, text):
            writes.append(text)

        def flush(self):
            pass

    monkeypatch.setattr("sys.stderr", Err())
    say("[1/2] frame 1 LiDAR: 10 points")
    say()
    assert writes == ["[1/2] frame 1 LiDAR: 10 points\n", "\n"]


def test_the_command_line_prints_no_line_to_stderr_in_two_writes():
    """print(..., file=sys.stderr) writes the text and the newline apart."""
    found = []
    for path in [ROOT / "cli.py", *sorted((ROOT / "commands").glob("*.py"))]:
        for node in ast.walk(ast.parse(path.read_text())):
            if (isinstance(node, ast.Call) and getattr(node.func, "id", None) == "print"
                    and any(k.arg == "file" and ast.unparse(k.value) == "sys.stderr"
                            for k in node.keywords)):
                found.append(f"{path.name}:{node.lineno}")
    assert not found, found

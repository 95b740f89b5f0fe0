"""The command line's runtime requirements carry what its main job needs: ``make demo``
on a fresh machine installs only ``requirements.txt`` (the Makefile's venv target), and
must then cast with Embree and the compiled library and draw the cloud's picture."""

from pathlib import Path

from packaging.markers import default_environment
from packaging.requirements import Requirement

ROOT = Path(__file__).resolve().parents[2]


def runtime_requirements():
    reqs = {}
    for line in (ROOT / "requirements.txt").read_text().splitlines():
        line = line.split("#", 1)[0].strip()
        if line:
            req = Requirement(line)
            if req.marker is None or req.marker.evaluate(default_environment()):
                reqs[req.name.lower()] = req
    return reqs


def test_runtime_requirements_install_the_demos_backend_and_pictures():
    reqs = runtime_requirements()
    assert "embreex" in reqs, "Embree is not installed with the runtime requirements here"
    assert "matplotlib" in reqs, "the demo's picture needs matplotlib"
    for name in ("embreex", "matplotlib"):
        assert str(reqs[name].specifier).startswith("=="), f"{name} is not pinned"


def test_embreex_is_required_only_where_it_has_wheels():
    """Linux x64 and Windows x64 (PyPI's embreex 4 wheels); not macOS, not Linux arm64."""
    line = next(ln for ln in (ROOT / "requirements.txt").read_text().splitlines()
                if ln.startswith("embreex"))
    marker = Requirement(line).marker
    env = default_environment()
    for plat, machine, want in (("linux", "x86_64", True), ("win32", "AMD64", True),
                                ("darwin", "arm64", False), ("darwin", "x86_64", False),
                                ("linux", "aarch64", False)):
        assert marker.evaluate({**env, "sys_platform": plat,
                                "platform_machine": machine}) is want, (plat, machine)


def test_demo_says_which_backend_ran_and_draws_its_picture(demo_run):
    out, summary, proc = demo_run
    assert summary["backend"] == "embree", summary["backend_why"]
    assert summary["backend_why"].startswith("Embree with the compiled loop")
    assert f"Ray casting: {summary['backend_why']}." in proc.stdout
    import json

    side = json.loads(Path(summary["point_cloud"]).with_suffix(".json").read_text())
    assert side["backend"] == "embree"
    picture = Path(summary["picture"])
    assert picture.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n" and picture.stat().st_size > 50_000

"""Imports flow one way, read from the source (every ``import`` statement, those inside
functions too, which an import-time check never sees):

- the floors of the house: the command line and the UI (commands, operators, ui) above
  properties, properties above the Blender adapters (``blender``), those above the core;
  nothing imports a floor above its own, and the three top rooms do not import each
  other;
- the core never imports Blender's modules (``bpy``, ``mathutils``, ...; one exception,
  ``BLENDER_IN_CORE``) nor anything of the package outside it but ``version``;
- within the core, a stage imports only itself and the stages before it in the flow of
  data: the order docs/architecture.md lists them in (``STAGES``, checked against it).
"""

import ast
import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
PACKAGE = ROOT / "rls_addon"

# the floors, top first; rooms on one floor do not import each other
FLOORS = [["__main__"], ["__init__"], ["registration"], ["cli"],
          ["commands", "operators", "ui"], ["properties"], ["blender"], ["core"], ["version"]]
# the core's stages, last in the flow of data first (a stage may import those below it);
# stages on one line are peers that may import each other
STAGES = [["live"], ["study"], ["scan"], ["evaluate"], ["traffic"], ["roads"], ["metrics"],
          ["device"], ["output"], ["physics"], ["world"], ["points"], ["casting"], ["scene"],
          ["labels", "choices"], ["progress"], ["native"], ["stop_signals"], ["errors"]]
BLENDER_MODULES = {"bpy", "mathutils", "bmesh", "gpu", "gpu_extras", "bpy_extras",
                   "bl_math", "blf", "aud", "idprop", "imbuf", "freestyle"}
# Blender's BVHTree backend: ``mathutils`` only, imported when a caster is built (the
# core still imports without Blender: test_core_imports_without_bpy), because the core
# chooses it by name as the fallback of every other backend (casting.caster_factory)
BLENDER_IN_CORE = {"rls_addon/core/casting/bvhtree.py": {"mathutils"}}


def _rank(groups):
    return {name: k for k, names in enumerate(groups) for name in names}


FLOOR, STAGE = _rank(FLOORS), _rank(STAGES)


def module_name(path, base=ROOT):
    parts = list(path.relative_to(base).with_suffix("").parts)
    if parts[-1] == "__init__" and len(parts) > 1:
        parts = parts[:-1]
    return ".".join(parts)


def imports(path, modules, base=ROOT):
    """(line, imported module) of every import in ``path``: relative imports resolved,
    ``from X import name`` taken as ``X.name`` where that is a module of the package."""
    name = module_name(path, base)
    package = name.split(".") if path.name == "__init__.py" else name.split(".")[:-1]
    for node in ast.walk(ast.parse(path.read_text(), str(path))):
        if isinstance(node, ast.Import):
            for alias in node.names:
                yield node.lineno, alias.name
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = package[:len(package) - (node.level - 1)]
                mod = ".".join(base + ([node.module] if node.module else []))
            else:
                mod = node.module
            for alias in node.names:
                sub = f"{mod}.{alias.name}"
                yield node.lineno, sub if sub in modules else mod


def floor_of(module):
    """The floor (``FLOORS``) a module of the package stands on."""
    parts = module.split(".")
    return "__init__" if len(parts) == 1 else parts[1]


def stage_of(module):
    """The core stage (``STAGES``) of a module of ``rls_addon.core`` (None: the package)."""
    parts = module.split(".")
    return parts[2] if len(parts) > 2 else None


def wrong_imports(root=PACKAGE):
    """Every import against the rules, as 'file:line: what' lines."""
    base = root.parent
    files = sorted(root.rglob("*.py"))
    modules = {module_name(p, base) for p in files}
    bad = []
    for path in files:
        me = module_name(path, base)
        where = f"{path.relative_to(base)}"
        my_floor = floor_of(me)
        for line, target in imports(path, modules, base):
            top = target.split(".")[0]
            at = f"{where}:{line}: imports {target}"
            if my_floor == "core" and top in BLENDER_MODULES \
                    and top not in BLENDER_IN_CORE.get(where, ()):
                bad.append(f"{at} (the core never imports Blender)")
            if top != "rls_addon":
                continue
            floor = floor_of(target)
            if floor not in FLOOR or my_floor not in FLOOR:
                bad.append(f"{at} (a room not in FLOORS: add it, and to docs/architecture.md)")
                continue
            if floor != my_floor and FLOOR[floor] <= FLOOR[my_floor]:
                bad.append(f"{at} ({my_floor} may not import {floor}: floors run "
                           f"{' -> '.join('/'.join(f) for f in FLOORS)})")
            if my_floor == "core" and floor == "core":
                mine, theirs = stage_of(me), stage_of(target)
                if mine is None or theirs is None or mine == theirs:
                    continue
                if mine not in STAGE or theirs not in STAGE:
                    bad.append(f"{at} (a core stage not in STAGES: add it, in the order of "
                               "docs/architecture.md)")
                elif STAGE[theirs] < STAGE[mine]:
                    bad.append(f"{at} (core/{mine} comes before core/{theirs} in the flow of "
                               "data: it may not import it)")
    return bad


def test_imports_flow_one_way():
    bad = wrong_imports()
    assert not bad, "imports against the house's direction:\n" + "\n".join(bad)


def test_every_room_and_stage_is_placed():
    """A new top-level room or core stage has a place in FLOORS / STAGES (and so in
    docs/architecture.md); the new folders are among them."""
    rooms = {p.stem if p.is_file() else p.name for p in PACKAGE.iterdir()
             if (p.suffix == ".py" or (p / "__init__.py").exists())}
    assert rooms == set(FLOOR), rooms ^ set(FLOOR)
    core = PACKAGE / "core"
    stages = {p.stem if p.is_file() else p.name for p in core.iterdir()
              if (p.suffix == ".py" and p.stem != "__init__") or (p / "__init__.py").exists()}
    assert stages == set(STAGE), stages ^ set(STAGE)
    for folder in ("live", "evaluate/detector", "device/families"):
        assert (core / folder / "__init__.py").exists(), folder


def test_the_stages_are_in_the_order_docs_architecture_gives():
    """The core's listing in docs/architecture.md ('rls_addon/core/' then a line per
    stage, 'name/' or 'name.py') names the stages in the order of STAGES."""
    text = (ROOT / "docs" / "architecture.md").read_text()
    block = text[re.search(r"^rls_addon/core/\s", text, re.M).start():]
    block = block[:re.search(r"^rls_addon/version.py|^```", block, re.M).start()]
    listed = []
    for line in block.splitlines()[1:]:
        m = re.match(r"^  ([a-z_]+(?:/|\.py)(?:, [a-z_]+(?:/|\.py))*)(\s|$)", line)
        if m:
            listed += re.findall(r"([a-z_]+)(?:/|\.py)", m.group(1))
    assert listed == [n for names in STAGES for n in names]


@pytest.mark.parametrize("case", ["upward", "blender", "stage"])
def test_a_wrong_import_is_caught(tmp_path, case):
    """The checker finds each kind of wrong import in a copy of the package with one
    planted: the core importing an operator, the core importing bpy inside a function,
    an earlier stage (scan) importing a later one (study)."""
    import shutil

    copy = tmp_path / "rls_addon"
    shutil.copytree(PACKAGE, copy, ignore=shutil.ignore_patterns("*.so", "*.dll", "*.dylib",
                                                                 "__pycache__", "c"))
    target = copy / "core" / "scan" / "frames.py"
    planted = {"upward": "from ...operators import scan as _s\n",
               "blender": "def _f():\n    import bpy\n    return bpy\n",
               "stage": "from ..study import loop as _l\n"}[case]
    target.write_text(target.read_text() + "\n" + planted)
    bad = wrong_imports(copy)
    assert len(bad) == 1 and "rls_addon/core/scan/frames.py" in bad[0], bad


def circles(root=PACKAGE):
    """Groups of modules that import each other in a loop (imports inside functions
    count: a loop closed by a late import is still a loop), each as a sorted list."""
    base = root.parent
    files = sorted(root.rglob("*.py"))
    modules = {module_name(p, base) for p in files}
    graph = {}
    for path in files:
        me = graph.setdefault(module_name(path, base), set())
        for _, target in imports(path, modules, base):
            while target not in modules and "." in target:
                target = target.rsplit(".", 1)[0]
            name = module_name(path, base)
            if target in modules and target != name and not name.startswith(target + "."):
                me.add(target)  # a module's own package (its __init__) is not a loop
    found, index, low, stack, on = [], {}, {}, [], set()

    def visit(v):  # Tarjan's strongly connected components
        index[v] = low[v] = len(index)
        stack.append(v)
        on.add(v)
        for w in graph[v]:
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            group = []
            while True:
                w = stack.pop()
                on.discard(w)
                group.append(w)
                if w == v:
                    break
            if len(group) > 1:
                found.append(sorted(group))

    for v in sorted(graph):
        if v not in index:
            visit(v)
    return found


def test_no_circles():
    """No modules import each other in a loop (output/io had bag_writer -> paths ->
    formats -> bag_writer, closed by an import inside a function)."""
    assert circles() == []


def test_a_circle_is_caught(tmp_path):
    import shutil

    copy = tmp_path / "rls_addon"
    shutil.copytree(PACKAGE, copy, ignore=shutil.ignore_patterns("*.so", "*.dll", "*.dylib",
                                                                 "__pycache__", "c"))
    names = copy / "core" / "output" / "io" / "names.py"
    names.write_text(names.read_text() + "\n\ndef _f():\n    from .paths import output_path\n"
                     "    return output_path\n")
    assert circles(copy) == [["rls_addon.core.output.io.bag_writer",
                              "rls_addon.core.output.io.formats",
                              "rls_addon.core.output.io.names",
                              "rls_addon.core.output.io.paths"]]

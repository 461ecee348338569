"""The layers of docs/architecture.md, checked on the source: ``sim.core`` at the bottom (standard
library and numpy only), ``aircraft``, ``guidance``, ``avoidance`` above it (from ``sim`` only
``sim.core``, and not each other), the engine (the rest of ``sim``) on top. Imports under
``if TYPE_CHECKING:`` name types only and are not counted."""

from __future__ import annotations

import ast
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
PACKAGES = ("sim", "aircraft", "guidance", "avoidance")
MIDDLE = ("aircraft", "guidance", "avoidance")


def _runtime_imports(tree: ast.Module) -> list[tuple[int, str]]:
    """(line, module) of every absolute import outside ``if TYPE_CHECKING:`` blocks."""
    skip: set[int] = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.If) and "TYPE_CHECKING" in ast.unparse(node.test):
            skip.update(id(n) for stmt in node.body for n in ast.walk(stmt))
    out = []
    for node in ast.walk(tree):
        if id(node) in skip:
            continue
        if isinstance(node, ast.Import):
            out += [(node.lineno, a.name) for a in node.names]
        elif isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
            out.append((node.lineno, node.module))
    return out


def violations(module_path: Path, source: str) -> list[str]:
    """Forbidden imports of one module, given its path relative to the project root."""
    parts = module_path.parts
    layer = "core" if parts[:2] == ("sim", "core") else parts[0]
    found = []
    for line, mod in _runtime_imports(ast.parse(source)):
        top = mod.split(".")[0]
        if layer == "core":
            ok = mod == "sim.core" or mod.startswith("sim.core.") or top == "numpy" or top in sys.stdlib_module_names
        elif layer in MIDDLE:
            ok = top not in PACKAGES or top == layer or mod == "sim.core" or mod.startswith("sim.core.")
        else:
            ok = True
        if not ok:
            found.append(f"{module_path}:{line}: {layer} imports {mod}")
    return found


def _project_modules():
    for pkg in PACKAGES:
        for path in sorted((ROOT / pkg).rglob("*.py")):
            yield path.relative_to(ROOT), path.read_text(encoding="utf-8")


def test_every_module_keeps_its_layer():
    bad = [v for rel, src in _project_modules() for v in violations(rel, src)]
    assert not bad, "\n".join(bad)


@pytest.mark.parametrize(
    "where, source",
    [
        ("avoidance/probe.py", "from sim.vehicle import Vehicle\n"),  # a planner reaching into the engine
        ("guidance/mptp/probe.py", "import avoidance.reachset.planner\n"),  # one middle package into another
        ("aircraft/probe.py", "from guidance.l1 import L1Guidance\n"),
        ("sim/core/probe.py", "from shapely.geometry import Polygon\n"),  # core: numpy and stdlib only
        ("sim/core/probe.py", "from sim.geodesy import GeoPoint\n"),
    ],
)
def test_a_forbidden_import_on_a_temporary_module_fails_the_check(tmp_path, where, source):
    probe = tmp_path / where
    probe.parent.mkdir(parents=True)
    probe.write_text(source)
    assert violations(Path(where), probe.read_text()), f"{where} should break the layering"


def test_type_only_and_allowed_imports_pass():
    ok = (
        "from __future__ import annotations\nfrom typing import TYPE_CHECKING\nimport numpy as np\n"
        "from sim.core.plan import Plan\nif TYPE_CHECKING:\n    from shapely.geometry import Polygon\n"
    )
    assert violations(Path("sim/core/probe.py"), ok) == []
    assert violations(Path("avoidance/probe.py"), ok + "import shapely\nfrom avoidance.reachset import grid\n") == []
    assert violations(Path("sim/probe.py"), "from avoidance.reachset import grid\n") == []  # the engine wires

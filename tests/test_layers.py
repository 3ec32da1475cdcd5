"""The house: the library never imports the study, no modules import each other in a loop, none is over 600 lines.

The library (``anseg/`` outside ``anseg/study/``) is what a user imports to
segment and train; the study regenerates the paper's tables on top of it.
Imports inside functions count as much as those at the top of a module.
"""

from __future__ import annotations

import ast
from pathlib import Path

PACKAGE = Path(__file__).resolve().parents[1] / "anseg"


def module_name(path: Path) -> str:
    parts = path.relative_to(PACKAGE.parent).with_suffix("").parts
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def imports(path: Path) -> set[str]:
    """The anseg modules ``path`` imports, anywhere in it (``from anseg import x`` names module ``anseg.x``)."""
    found = set()
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.Import):
            found |= {alias.name for alias in node.names if alias.name.startswith("anseg")}
        elif isinstance(node, ast.ImportFrom) and node.module and node.module.startswith("anseg"):
            found |= {f"{node.module}.{alias.name}" for alias in node.names} | {node.module}
    modules = {module_name(p) for p in PACKAGE.rglob("*.py")}
    return {name for name in found if name in modules}


def graph() -> dict[str, set[str]]:
    return {module_name(path): imports(path) - {module_name(path)} for path in PACKAGE.rglob("*.py")}


def test_the_library_never_imports_the_study():
    offenders = {module: sorted(i for i in imported if i.startswith("anseg.study"))
                 for module, imported in graph().items() if not module.startswith("anseg.study")}
    assert {m: i for m, i in offenders.items() if i} == {}


def test_no_modules_import_each_other_in_a_loop():
    edges = {m: {i for i in imported if i != "anseg" and not m.startswith(i + ".")} for m, imported in graph().items()}
    state: dict[str, int] = {}  # 1 on the current path, 2 finished

    def loop_from(module: str, path: list[str]) -> list[str] | None:
        state[module] = 1
        for other in sorted(edges.get(module, ())):
            if state.get(other) == 1:
                return path + [module, other]
            if other not in state and (found := loop_from(other, path + [module])):
                return found
        state[module] = 2
        return None

    for module in sorted(edges):
        if module not in state:
            assert loop_from(module, []) is None


MAX_MODULE_LINES = 600  # a room one reads in a sitting; a larger one holds two jobs


def test_no_module_is_longer_than_a_sitting():
    long = {module_name(p): n for p in PACKAGE.rglob("*.py") if (n := len(p.read_text().splitlines())) > MAX_MODULE_LINES}
    assert long == {}

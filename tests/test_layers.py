"""The package's structure: no import cycle among its modules, imports only go down the layers.

Every `import`/`from ... import` of a wallbatch module is read with `ast`, at module level and
inside functions alike, so a cycle cannot hide behind a function-level import.
"""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

SRC = Path(__file__).resolve().parents[1] / "src" / "wallbatch"

# Lowest first: a module may import only from its own layer's folder or from lower layers.
LAYERS = ["version", "units", "expr", "stats", "geometry", "styles", "config", "scene", "engine", "io", "batch", "lammps",
          "api", "convergence", "cli"]


def _module_name(path: Path) -> str:
    rel = path.relative_to(SRC.parent).with_suffix("")
    parts = list(rel.parts)
    if parts[-1] == "__init__":
        parts = parts[:-1]
    return ".".join(parts)


def _modules() -> dict[str, Path]:
    return {_module_name(p): p for p in SRC.rglob("*.py")}


def _imports(name: str, path: Path, known: set[str]) -> set[str]:
    """The wallbatch modules that `name` imports (any depth, any place in the file)."""
    tree = ast.parse(path.read_text(), filename=str(path))
    pkg = name if path.name == "__init__.py" else name.rpartition(".")[0]
    out: set[str] = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            targets = [a.name for a in node.names]
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:
                up = pkg.split(".")
                up = up[: len(up) - (node.level - 1)]
                base = ".".join(up + ([base] if base else []))
            targets = [f"{base}.{a.name}" if f"{base}.{a.name}" in known else base for a in node.names]
        else:
            continue
        for t in targets:
            while t and t not in known:
                t = t.rpartition(".")[0]
            if t and t.startswith("wallbatch") and t != name:
                out.add(t)
    return out


def _graph() -> dict[str, set[str]]:
    mods = _modules()
    known = set(mods)
    return {name: _imports(name, path, known) for name, path in mods.items()}


def _layer(module: str) -> int:
    parts = module.split(".")
    if len(parts) == 1:  # the package's own __init__: the top
        return len(LAYERS)
    return LAYERS.index(parts[1])


def test_every_module_belongs_to_a_layer():
    unknown = sorted(m for m in _modules() if m != "wallbatch" and m.split(".")[1] not in LAYERS)
    assert not unknown, f"modules outside the layer list (add them to LAYERS in {__file__}): {unknown}"


@pytest.mark.slow
def test_no_import_cycle():
    graph = _graph()
    state: dict[str, int] = {}
    stack: list[str] = []

    def visit(m: str) -> None:
        state[m] = 1
        stack.append(m)
        for n in sorted(graph.get(m, ())):
            if n == "wallbatch":
                continue  # the top-level __init__ only re-exports lazily
            if state.get(n) == 1:
                cycle = stack[stack.index(n):] + [n]
                pytest.fail("import cycle: " + " -> ".join(cycle))
            if n not in state:
                visit(n)
        stack.pop()
        state[m] = 2

    for m in sorted(graph):
        if m not in state:
            visit(m)


@pytest.mark.slow
def test_imports_only_go_down_the_layers():
    bad = []
    for m, deps in _graph().items():
        if m == "wallbatch":
            continue
        for d in deps:
            if d == "wallbatch":
                bad.append(f"{m} imports the top-level package")
            elif _layer(d) > _layer(m):
                bad.append(f"{m} -> {d}")
    assert not bad, "imports going up the layers:\n" + "\n".join(sorted(bad))


def test_every_subpackage_says_what_lives_there_and_what_it_may_import():
    for init in SRC.glob("*/__init__.py"):
        doc = ast.get_docstring(ast.parse(init.read_text())) or ""
        assert "May import" in doc, f"{init}: the docstring must say what the folder may import"

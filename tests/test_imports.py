"""The prbdm import graph has no cycles (issue 17 item 6): read from the sources with ``ast``, not
by importing them. Two graphs: the module-level imports (what runs at import time), and every
import including those inside functions (a lazy import that closes a cycle still ties two modules
into one, as ``export`` <-> ``simulate`` once did)."""
from __future__ import annotations

import ast
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
PACKAGE = ROOT / "prbdm"


def module_name(path: Path) -> str:
    parts = list(path.relative_to(ROOT).with_suffix("").parts)
    if parts[-1] == "__init__":
        parts = parts[:-1]
    return ".".join(parts)


MODULES = {module_name(p): p for p in PACKAGE.rglob("*.py")}


def targets(module: str, path: Path, node) -> set[str]:
    """The prbdm modules an import statement names (``from .a import b`` names ``a`` and, if it
    is a module, ``a.b``)."""
    if isinstance(node, ast.Import):
        names = [a.name for a in node.names]
    else:
        if node.level:
            base = module.split(".")
            if path.name != "__init__.py":
                base = base[:-1]                  # a module's package
            base = base[:len(base) - (node.level - 1)]
            prefix = ".".join(base + ([node.module] if node.module else []))
        else:
            prefix = node.module or ""
        subs = [f"{prefix}.{a.name}" for a in node.names]
        # `from . import a` names the submodule a, not its package, when a is a module: the
        # package is then only being initialised, which imports nothing of its own
        names = subs + ([prefix] if node.module or not all(n in MODULES for n in subs) else [])
    return {n for n in names if n in MODULES and n != module}


def module_level(tree):
    """Statements run at import time: the module body, into if/try/with blocks, not functions
    or classes."""
    stack = list(tree.body)
    while stack:
        node = stack.pop()
        yield node
        if isinstance(node, (ast.If, ast.Try, ast.With)):
            for block in ("body", "orelse", "finalbody"):
                stack += getattr(node, block, [])
            for h in getattr(node, "handlers", []):
                stack += h.body


def graph(lazy: bool) -> dict[str, set[str]]:
    g = {}
    for m, p in MODULES.items():
        tree = ast.parse(p.read_text(encoding="utf-8"))
        nodes = ast.walk(tree) if lazy else module_level(tree)
        g[m] = set().union(*(targets(m, p, n) for n in nodes
                             if isinstance(n, (ast.Import, ast.ImportFrom))))
    return g


def find_cycle(g: dict[str, set[str]]) -> list[str] | None:
    """One cycle of ``g`` as a list of modules (first == last), or None."""
    state = {}                                     # 1 on the path, 2 done
    path = []

    def visit(v):
        state[v] = 1
        path.append(v)
        for w in sorted(g[v]):
            if state.get(w) == 1:
                return path[path.index(w):] + [w]
            if w not in state:
                found = visit(w)
                if found:
                    return found
        state[v] = 2
        path.pop()
        return None

    for v in sorted(g):
        if v not in state:
            found = visit(v)
            if found:
                return found
    return None


def test_the_cycle_finder_finds_a_cycle():
    assert find_cycle({"a": {"b"}, "b": {"c"}, "c": {"a"}}) == ["a", "b", "c", "a"]
    assert find_cycle({"a": {"b"}, "b": set(), "c": {"a", "b"}}) is None


def test_the_graph_sees_the_imports():
    g = graph(lazy=True)
    assert "prbdm.signals" in g["prbdm.simulate"] and "prbdm.signals" in g["prbdm.export.verify"]
    assert "prbdm.truth" in g["prbdm.simulate"]    # beam_modes: the truth's beam model


@pytest.mark.parametrize("lazy", [False, True], ids=["module-level", "with-lazy-imports"])
def test_the_import_graph_is_acyclic(lazy):
    cycle = find_cycle(graph(lazy))
    assert cycle is None, "import cycle: " + " -> ".join(cycle)


def test_the_library_never_imports_the_commands():
    """prbdm.commands is the command line's; the library below it (and its shared constants and
    file writing, prbdm.constants and prbdm.files) never reaches up into it (issue 17 item 5)."""
    g = graph(lazy=True)
    up = {m: sorted(t for t in targets if t.startswith("prbdm.commands"))
          for m, targets in g.items()
          if not (m.startswith("prbdm.commands") or m == "prbdm.cli")}
    assert {m: t for m, t in up.items() if t} == {}
    assert g["prbdm.constants"] == set() and g["prbdm.files"] == set()

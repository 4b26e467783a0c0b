"""The import contract of docs/architecture.md, read from the source with ``ast``: every
import statement counts, at module top or inside a function.

- ``vision`` imports nothing of ``fydpad`` or ``teleop``;
- ``teleop`` imports nothing of ``fydpad``;
- no import cycle anywhere;
- a library module imports at its top; an import inside a function says why in a comment
  on its line or just above it (or above the block of imports it opens). Command modules
  (``fydpad.cli``, ``fydpad.commands.*``, ``teleop.cli``) import their libraries inside the
  command for a fast ``--help``, the one reason there, so they are not checked.
"""

from __future__ import annotations

import ast
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
PACKAGES = ("vision", "fydpad", "teleop")

def _modules() -> dict[str, Path]:
    mods = {}
    for pkg in PACKAGES:
        for path in (ROOT / pkg).rglob("*.py"):
            parts = list(path.relative_to(ROOT).with_suffix("").parts)
            if parts[-1] == "__init__":
                parts.pop()
            mods[".".join(parts)] = path
    return mods


MODULES = _modules()


def _resolve(name: str) -> str | None:
    """The project module ``name`` refers to (a module, or a name inside one)."""
    parts = name.split(".")
    for i in range(len(parts), 0, -1):
        candidate = ".".join(parts[:i])
        if candidate in MODULES:
            return candidate
    return None


def _imports(module: str) -> set[str]:
    path = MODULES[module]
    package = module.split(".") if path.name == "__init__.py" else module.split(".")[:-1]
    found: set[str] = set()
    for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
        if isinstance(node, ast.Import):
            names = [a.name for a in node.names]
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:
                base = ".".join(package[:len(package) - node.level + 1] + ([base] if base else []))
            names = [base] + [f"{base}.{a.name}" for a in node.names]
        else:
            continue
        for name in names:
            target = _resolve(name)
            if target is not None and target != module:
                found.add(target)
    return found


GRAPH = {m: _imports(m) for m in MODULES}


def _cycles() -> set[frozenset[str]]:
    """The strongly connected components with more than one module (Tarjan)."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on_stack: set[str] = set()
    out: set[frozenset[str]] = set()

    def visit(v: str) -> None:
        index[v] = low[v] = len(index)
        stack.append(v)
        on_stack.add(v)
        for w in GRAPH[v]:
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on_stack:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            comp = set()
            while True:
                w = stack.pop()
                on_stack.discard(w)
                comp.add(w)
                if w == v:
                    break
            if len(comp) > 1:
                out.add(frozenset(comp))

    for v in sorted(GRAPH):
        if v not in index:
            visit(v)
    return out


def _crossing(src: str, forbidden: tuple[str, ...]) -> list[str]:
    return sorted(f"{m} imports {t}" for m, targets in GRAPH.items()
                  if m.split(".")[0] == src for t in targets
                  if t.split(".")[0] in forbidden)


def _is_command(module: str) -> bool:
    return module in ("fydpad.cli", "teleop.cli") or module.startswith("fydpad.commands.")


def unexplained_local_imports(source: str) -> list[int]:
    """Lines of the imports inside functions with no comment on their lines, nor on the
    line above them or above the run of imports they stand in."""
    lines = source.splitlines()
    out: set[int] = set()
    for fn in ast.walk(ast.parse(source)):
        if not isinstance(fn, ast.FunctionDef | ast.AsyncFunctionDef):
            continue
        imports = [n for n in ast.walk(fn) if isinstance(n, ast.Import | ast.ImportFrom)]
        in_import = {i for n in imports for i in range(n.lineno, (n.end_lineno or n.lineno) + 1)}
        for n in imports:
            if any("#" in lines[i - 1] for i in range(n.lineno, (n.end_lineno or n.lineno) + 1)):
                continue
            above = n.lineno - 1
            while above in in_import:
                above -= 1
            if above < 1 or not lines[above - 1].strip().startswith("#"):
                out.add(n.lineno)
    return sorted(out)


def test_every_local_import_in_library_code_says_why():
    found = {m: unexplained_local_imports(p.read_text(encoding="utf-8"))
             for m, p in MODULES.items()
             if not _is_command(m)}
    assert {m: lines for m, lines in found.items() if lines} == {}


def test_the_local_import_check_sees_a_missing_reason():
    source = (
        "def f():\n"
        "    import os\n"                       # 2: no reason
        "    # lazy: a reason for the block\n"
        "    import sys\n"
        "    from json import (\n"
        "        dumps,\n"
        "    )\n"
        "    x = 1\n"
        "    import re  # lazy: on its line\n"
        "    import csv\n"                      # 10: the line above is code
    )
    assert unexplained_local_imports(source) == [2, 10]


def test_vision_imports_nothing_of_the_other_packages():
    assert _crossing("vision", ("fydpad", "teleop")) == []


def test_teleop_imports_only_vision():
    assert _crossing("teleop", ("fydpad",)) == []


def test_no_import_cycles():
    assert _cycles() == set()


def test_the_checker_sees_a_cycle_and_a_crossing():
    # The checks above must be able to fail: a cycle and a crossing added by hand are found.
    GRAPH["vision.fake_a"] = {"vision.fake_b", "teleop.link"}
    GRAPH["vision.fake_b"] = {"vision.fake_a"}
    try:
        assert frozenset({"vision.fake_a", "vision.fake_b"}) in _cycles()
        assert "vision.fake_a imports teleop.link" in _crossing("vision", ("teleop",))
    finally:
        del GRAPH["vision.fake_a"], GRAPH["vision.fake_b"]

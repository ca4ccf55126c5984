"""The house's layers, read from the source: no import circles among the add-on's modules
nor among core's packages, no ``bpy`` under ``core/``, and Blender imported only by the glue
(``operators/``, ``ui/``).

Every ``import`` statement counts, also one inside a function (a deferred import is still a
dependency), except those under ``if TYPE_CHECKING:``."""
from __future__ import annotations

import ast
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
PARTS = ("core", "operators", "ui", "cli", "install")
GLUE = ("operators", "ui")


def _modules() -> dict[str, Path]:
    """{dotted module name relative to the root: its file} for the add-on's own code."""
    files = [ROOT / "__init__.py", ROOT / "batch.py", ROOT / "micromesh_path.py"]
    for part in PARTS:
        files += sorted((ROOT / part).rglob("*.py"))
    out = {}
    for f in files:
        rel = f.relative_to(ROOT).with_suffix("")
        parts = list(rel.parts)
        if parts[-1] == "__init__":
            parts = parts[:-1]
        out[".".join(parts)] = f
    return out


def _imports(name: str, path: Path) -> list[tuple]:
    """(imported dotted name, line) of every import in ``path`` outside TYPE_CHECKING blocks,
    relative imports resolved against ``name`` (a package's ``__init__`` is the package)."""
    tree = ast.parse(path.read_text(encoding="utf-8"))
    skip = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.If) and "TYPE_CHECKING" in ast.unparse(node.test):
            skip.update(id(n) for n in ast.walk(node))
    package = name if path.name == "__init__.py" else name.rpartition(".")[0]
    found = []
    for node in ast.walk(tree):
        if id(node) in skip:
            continue
        if isinstance(node, ast.Import):
            found += [(a.name, node.lineno) for a in node.names]
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = package.split(".") if package else []
                base = base[:len(base) - (node.level - 1)] if node.level > 1 else base
                mod = ".".join(base + ([node.module] if node.module else []))
            else:
                mod = node.module
            # "from P import m" where m is a module is an arrow to m, otherwise one to P
            found += [(f"{mod}.{a.name}" if mod else a.name, node.lineno) for a in node.names]
            found.append((mod, node.lineno, [a.name for a in node.names]))
    return found


def _graph() -> dict[str, set[str]]:
    mods = _modules()
    graph = {}
    for name, path in mods.items():
        deps = set()
        for target, _, *names in _imports(name, path):
            t = target.removeprefix("micromesh.") if target != "micromesh" else ""
            if names and all(f"{t}.{n}".lstrip(".") in mods for n in names[0]):
                continue                  # only modules taken from the package: their arrows
            if t in mods and t != name:
                deps.add(t)
        graph[name] = deps
    return graph


def _circles(graph: dict[str, set[str]]) -> list[list[str]]:
    """Strongly connected components of more than one module (Tarjan)."""
    index, low, stack, on, out = {}, {}, [], set(), []

    def visit(v):
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
            comp = []
            while True:
                w = stack.pop()
                on.discard(w)
                comp.append(w)
                if w == v:
                    break
            if len(comp) > 1:
                out.append(sorted(comp))

    for v in sorted(graph):
        if v not in index:
            visit(v)
    return out


def test_the_reader_sees_the_house():
    mods = _modules()
    graph = _graph()
    assert "core.micro.micromesh" in mods and "operators.headless" in mods
    assert sum(len(d) for d in graph.values()) > 300          # the arrows are really read
    assert _circles({"a": {"b"}, "b": {"a"}, "c": {"a"}}) == [["a", "b"]]


def test_no_import_circles():
    assert _circles(_graph()) == []


def test_no_circles_among_cores_packages():
    """core's packages are layers: no package reaches back into one that reaches it."""
    graph = _graph()

    def package(m: str) -> str:
        return ".".join(m.split(".")[:2]) if m.startswith("core.") else m.split(".")[0]

    packages: dict[str, set[str]] = {}
    for a, deps in graph.items():
        packages.setdefault(package(a), set()).update(
            package(b) for b in deps if package(b) != package(a))
    assert _circles(packages) == []


def test_blender_only_in_the_glue():
    offenders = []
    for name, path in _modules().items():
        if name.split(".")[0] in GLUE:
            continue
        for target, line, *_ in _imports(name, path):
            if target.split(".")[0] == "bpy":
                offenders.append(f"{path.relative_to(ROOT)}:{line}")
    assert offenders == []


def test_no_blender_under_core():
    for name, path in _modules().items():
        if name.startswith("core"):
            assert "bpy" not in {t.split(".")[0] for t, *_ in _imports(name, path)}, path

"""The package's shape, read from its source with ``ast`` (docs/architecture.md): no import
circle among its modules, every folder imports only the folders below it, a small top level, and
no module over ``MAX_LINES`` lines but the named exceptions."""

from __future__ import annotations

import ast
from pathlib import Path


PACKAGE = Path(__file__).resolve().parent.parent / "aac_sumo"

#: The layers, bottom first. A folder is a subpackage of aac_sumo; ``core`` is the package's own
#: top-level modules (geometry, dynamics, barriers, world, references, prediction, metrics,
#: network, registry). Each may import what it names besides itself (docs/architecture.md).
ALLOWED: dict[str, set[str]] = {
    "kernels": set(),
    "config": set(),
    "core": {"kernels", "config"},
    "mpc": {"kernels", "config", "core"},
    "sim": {"kernels", "config", "core"},
    "coordination": {"kernels", "config", "core", "mpc"},
    "experiments": {"kernels", "config", "core", "mpc", "sim", "coordination"},
    "runs": {"kernels", "config", "core", "mpc", "sim", "coordination", "experiments"},
    "views": {"kernels", "config", "core", "mpc", "sim", "coordination", "experiments", "runs"},
    "tables": {"kernels", "config", "core", "mpc", "sim", "coordination", "experiments", "runs"},
    "tune": {"kernels", "config", "core", "mpc", "sim", "coordination", "experiments", "runs"},
    "stress": {"kernels", "config", "core", "mpc", "sim", "coordination", "experiments", "runs", "tables"},
    "cli": {"kernels", "config", "core", "mpc", "sim", "coordination", "experiments", "runs", "views", "tables", "tune",
            "stress", "root"},  # root: aac_sumo.__version__
    "root": set(),  # aac_sumo/__init__.py loads its public names lazily, by name
}
#: At most this many modules beside the subpackages in aac_sumo/ (``__init__.py`` not counted).
MAX_TOP_LEVEL = 12
#: No module is longer than this [lines] ...
MAX_LINES = 400


def module_name(path: Path) -> str:
    parts = list(path.relative_to(PACKAGE.parent).with_suffix("").parts)
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def package_modules() -> dict[str, Path]:
    return {module_name(p): p for p in sorted(PACKAGE.rglob("*.py"))}


def imports(path: Path, name: str, known: set[str]) -> set[str]:
    """The package's modules that ``path`` (module ``name``) imports, anywhere in it (inside
    functions too): ``from aac_sumo.x import y`` names the module ``aac_sumo.x.y`` when there
    is one, else ``aac_sumo.x``."""
    found = set()
    package = name if path.name == "__init__.py" else name.rpartition(".")[0]
    for node in ast.walk(ast.parse(path.read_text(), str(path))):
        if isinstance(node, ast.Import):
            found |= {a.name for a in node.names if a.name.split(".")[0] == "aac_sumo"}
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:
                stem = package.split(".")[: len(package.split(".")) - node.level + 1]
                base = ".".join(stem + ([node.module] if node.module else []))
            if base.split(".")[0] != "aac_sumo":
                continue
            for alias in node.names:
                found.add(f"{base}.{alias.name}" if f"{base}.{alias.name}" in known else base)
    return {m for m in found if m in known and m != name}


def graph() -> dict[str, set[str]]:
    modules = package_modules()
    return {name: imports(path, name, set(modules)) for name, path in modules.items()}


def folder(module: str) -> str:
    parts = module.split(".")
    if len(parts) == 1:
        return "root"
    return parts[1] if (PACKAGE / parts[1]).is_dir() else "core"


def circles(edges: dict[str, set[str]]) -> list[list[str]]:
    """Every import circle (a strongly connected set of two or more modules), Tarjan's way."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    found: list[list[str]] = []

    def visit(v: str) -> None:
        index[v] = low[v] = len(index)
        stack.append(v)
        for w in sorted(edges[v]):
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in stack:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            group = []
            while True:
                w = stack.pop()
                group.append(w)
                if w == v:
                    break
            if len(group) > 1:
                found.append(sorted(group))

    for v in sorted(edges):
        if v not in index:
            visit(v)
    return found


def test_the_reader_sees_the_imports_it_should():
    """An independent look at three modules whose imports are known: the checks below would pass
    vacuously on a reader that found nothing."""
    edges = graph()
    assert "aac_sumo.kernels.motion" in edges["aac_sumo.coordination.tracking"]
    assert "aac_sumo.cli.common" in edges["aac_sumo.cli.views"]
    assert "aac_sumo.runs.runner" in edges["aac_sumo.cli.app"]  # an import inside a function counts
    assert edges["aac_sumo.kernels.paths"] == set()


def test_no_import_circle():
    assert circles(graph()) == []


def test_each_folder_imports_only_the_layers_below_it():
    edges = graph()
    assert set(map(folder, edges)) <= set(ALLOWED), "a new folder: give it its place in ALLOWED and docs/architecture.md"
    wrong = sorted(f"{a} -> {b}" for a, targets in edges.items() for b in targets
                   if folder(a) != folder(b) and folder(b) not in ALLOWED[folder(a)])
    assert wrong == []


def test_the_top_level_stays_small():
    top = sorted(p.name for p in PACKAGE.glob("*.py") if p.name != "__init__.py")
    assert len(top) <= MAX_TOP_LEVEL, top


def test_no_module_is_too_long():
    lengths = {str(p.relative_to(PACKAGE)): len(p.read_text().splitlines()) for p in PACKAGE.rglob("*.py")}
    assert {f: n for f, n in lengths.items() if n > MAX_LINES} == {}

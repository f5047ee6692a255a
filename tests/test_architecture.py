"""The package's layers (docs/architecture.md), checked on the source's imports.

Every import statement of every module under src/facemotion counts, wherever it is (module
level, inside a function, under ``TYPE_CHECKING``), relative or absolute, and so does a string
that names a module of the package exactly (the lazy tables: ``("facemotion.io.registry",
"read_recording")``). From these: no import circle between modules, and no module importing
from a higher layer or from another package of its own layer. Each check is also run on a
planted violation, so a check that sees nothing cannot pass unnoticed.
"""

from __future__ import annotations

import ast
import re
import shutil
from pathlib import Path

from helpers import REPO

SRC = REPO / "src"
TOP = "facemotion"
DOC = REPO / "docs" / "architecture.md"
TOP_LEVEL = "__init__"  # the table's name of the package's own __init__.py


def module_names(src: Path, top: str = TOP) -> dict[str, Path]:
    """Dotted module name -> file, for every .py file of the package ``top`` under ``src``."""
    names = {}
    for path in sorted((src / top).rglob("*.py")):
        parts = list(path.relative_to(src).with_suffix("").parts)
        if parts[-1] == "__init__":
            parts.pop()
        names[".".join(parts)] = path
    return names


def imported_modules(path: Path, module: str, modules: set[str], top: str = TOP) -> set[str]:
    """The modules of package ``top`` that ``module`` (the file ``path``) imports or names.

    ``from X import a`` is an import of X.a when that is a module, else of X. A name under
    ``top`` that is no module of it (a removed or misspelt path) is kept as it is, so the layer
    check reports it.
    """
    tree = ast.parse(path.read_text(encoding="utf-8"), filename=str(path))
    package = module if path.name == "__init__.py" else module.rpartition(".")[0]
    found: set[str] = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            found.update(alias.name for alias in node.names)
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = package.split(".")
                base = base[:len(base) - node.level + 1]
                source = ".".join(base + ([node.module] if node.module else []))
            else:
                source = node.module or ""
            for alias in node.names:
                sub = f"{source}.{alias.name}"
                found.add(sub if sub in modules else source)
        elif (isinstance(node, ast.Constant) and isinstance(node.value, str)
              and node.value in modules and "." in node.value):
            found.add(node.value)  # a lazy import by name
    return {m for m in found if m == top or m.startswith(top + ".")} - {module}


def import_graph(src: Path, top: str = TOP) -> dict[str, set[str]]:
    """Module -> the modules it imports, for the package ``top`` under ``src``."""
    files = module_names(src, top)
    return {m: imported_modules(p, m, set(files), top) for m, p in files.items()}


def circles(graph: dict[str, set[str]]) -> list[list[str]]:
    """The strongly connected components of more than one module (Tarjan), each sorted."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on_stack: set[str] = set()
    found: list[list[str]] = []

    def visit(v: str) -> None:
        index[v] = low[v] = len(index)
        stack.append(v)
        on_stack.add(v)
        for w in graph.get(v, ()):
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on_stack:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            component = []
            while True:
                w = stack.pop()
                on_stack.discard(w)
                component.append(w)
                if w == v:
                    break
            if len(component) > 1:
                found.append(sorted(component))

    for v in sorted(graph):
        if v not in index:
            visit(v)
    return sorted(found)


def read_layers(text: str) -> dict[str, int]:
    """Package or module name (under the top package) -> layer, from the markdown table whose
    header starts with ``| layer |``: one row per layer, the names in backticks."""
    lines = text.splitlines()
    start = next(i for i, line in enumerate(lines) if re.match(r"\|\s*layer\s*\|", line))
    layers: dict[str, int] = {}
    for line in lines[start + 2:]:
        if not line.startswith("|"):
            break
        cells = [c.strip() for c in line.strip().strip("|").split("|")]
        for name in re.findall(r"`([^`]+)`", cells[1]):
            assert name not in layers, f"{name} is in two layers"
            layers[name] = int(cells[0])
    return layers


def part(module: str) -> str:
    """The table's name for a module: its package or module directly under the top package."""
    parts = module.split(".")
    return parts[1] if len(parts) > 1 else TOP_LEVEL


def layer_violations(graph: dict[str, set[str]], layers: dict[str, int]) -> list[str]:
    """One line per import that goes up a layer or across to another package of the same one,
    or that involves a module in no layer."""
    problems = set()
    for module in sorted(graph):
        for target in sorted(graph[module]):
            a, b = part(module), part(target)
            if a == b:
                continue
            for name in (a, b):
                if name not in layers:
                    problems.add(f"{name} ({module} -> {target}) is in no layer of the table")
            if a not in layers or b not in layers:
                continue
            if layers[b] > layers[a]:
                problems.add(f"{module} (layer {layers[a]}) imports {target} from the higher "
                             f"layer {layers[b]}")
            elif layers[b] == layers[a]:
                problems.add(f"{module} imports {target}, another package of its layer "
                             f"{layers[a]}")
    return sorted(problems)


# --- the package as it is -------------------------------------------------------------------

def test_the_table_lists_every_part_of_the_package_once_in_ascending_layers():
    text = DOC.read_text(encoding="utf-8")
    layers = read_layers(text)
    parts = {part(m) for m in module_names(SRC)}
    assert set(layers) == parts, ("docs/architecture.md's layers and the package differ: "
                                  f"in the table only {sorted(set(layers) - parts)}, in the "
                                  f"package only {sorted(parts - set(layers))}")
    numbers = [int(m) for m in re.findall(r"^\|\s*(\d+)\s*\|", text, flags=re.MULTILINE)]
    assert numbers == list(range(len(numbers))), numbers


def test_no_import_circles():
    assert circles(import_graph(SRC)) == []


def test_every_import_stays_in_its_package_or_goes_down_a_layer():
    layers = read_layers(DOC.read_text(encoding="utf-8"))
    assert layer_violations(import_graph(SRC), layers) == []


def test_the_graph_is_not_empty_and_holds_known_edges():
    # A parser that missed every import would pass the two checks above.
    graph = import_graph(SRC)
    assert "facemotion.errors" in graph["facemotion.io.registry"]
    assert "facemotion.ingest.loading" in graph[TOP]                  # the lazy table
    assert "facemotion.lips.fitting" in graph["facemotion.lips"]      # inside a function
    assert sum(map(len, graph.values())) > 200


# --- the checks reject planted violations ---------------------------------------------------

def write_tree(root: Path, files: dict[str, str]) -> Path:
    for name, text in files.items():
        path = root / name
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(text, encoding="utf-8")
    return root


SYNTHETIC = {
    "facemotion/__init__.py": "from facemotion import low\n",
    "facemotion/low/__init__.py": "",
    "facemotion/low/a.py": "def f():\n    from . import b\n",           # relative, in a function
    "facemotion/low/b.py": "from typing import TYPE_CHECKING\n"
                           "if TYPE_CHECKING:\n    from facemotion.low.a import f\n",
    "facemotion/low/c.py": "from ..high import h\n",                     # up a layer, relative
    "facemotion/side/__init__.py": "import facemotion.low.c\n",           # across, absolute
    "facemotion/high/__init__.py": "",
    "facemotion/high/h.py": "TABLE = {'x': ('facemotion.low.b', 'g')}\n",   # lazy, down: fine
}
SYNTHETIC_LAYERS = """
| layer | packages | what |
| --- | --- | --- |
| 0 | `low`, `side` | the bottom |
| 1 | `high` | above it |
| 2 | `__init__` | the API |
"""


def test_the_graph_sees_every_kind_of_import(tmp_path):
    graph = import_graph(write_tree(tmp_path, SYNTHETIC))
    assert graph == {
        "facemotion": {"facemotion.low"},
        "facemotion.low": set(),
        "facemotion.low.a": {"facemotion.low.b"},
        "facemotion.low.b": {"facemotion.low.a"},
        "facemotion.low.c": {"facemotion.high.h"},
        "facemotion.side": {"facemotion.low.c"},
        "facemotion.high": set(),
        "facemotion.high.h": {"facemotion.low.b"},
    }


def test_circle_check_rejects_a_planted_circle(tmp_path):
    graph = import_graph(write_tree(tmp_path, SYNTHETIC))
    assert circles(graph) == [["facemotion.low.a", "facemotion.low.b"]]
    assert circles({"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}}) == [["a", "b", "c"]]
    assert circles({"a": {"b"}, "b": set()}) == []


def test_layer_check_rejects_an_upward_and_a_sideways_import(tmp_path):
    graph = import_graph(write_tree(tmp_path, SYNTHETIC))
    assert layer_violations(graph, read_layers(SYNTHETIC_LAYERS)) == [
        "facemotion.low.c (layer 0) imports facemotion.high.h from the higher layer 1",
        "facemotion.side imports facemotion.low.c, another package of its layer 0",
    ]
    # a package missing from the table is reported, not waved through
    assert ("side (facemotion.side -> facemotion.low.c) is in no layer of the table"
            in layer_violations(graph, {"low": 0, "high": 1, TOP_LEVEL: 2}))


def test_both_checks_reject_violations_planted_in_a_copy_of_the_package(tmp_path):
    shutil.copytree(SRC / TOP, tmp_path / TOP,
                    ignore=shutil.ignore_patterns("__pycache__", "*.pyc"))
    layers = read_layers(DOC.read_text(encoding="utf-8"))
    with open(tmp_path / TOP / "io" / "trc.py", "a", encoding="utf-8") as f:
        f.write("\n\ndef _planted():\n    from facemotion.study.sheet import read_sheet\n")
    with open(tmp_path / TOP / "ranking" / "gram.py", "a", encoding="utf-8") as f:
        f.write("\nfrom facemotion.plots import style\n")
    with open(tmp_path / TOP / "errors.py", "a", encoding="utf-8") as f:
        f.write("\nfrom facemotion.pivoted_qr import rank_markers\n")
    with open(tmp_path / TOP / "regions" / "prediction.py", "a", encoding="utf-8") as f:
        f.write("\nif False:\n    from facemotion.regions.selector import MarkerSelector\n")
    graph = import_graph(tmp_path)
    assert layer_violations(graph, layers) == [
        "facemotion.io.trc (layer 1) imports facemotion.study.sheet from the higher layer 5",
        "facemotion.ranking.gram imports facemotion.plots.style, another package of its "
        "layer 3",
        "pivoted_qr (facemotion.errors -> facemotion.pivoted_qr) is in no layer of the table",
    ]
    assert ["facemotion.regions.prediction", "facemotion.regions.selector"] in circles(graph)

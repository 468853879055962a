"""The packages of phid_ros import downwards only: the command line above the library, the
library above its numerics. A new import that breaks the order fails here, with its file."""

import ast
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1] / "phid_ros"

# lowest first; a package may import its own modules and those of any lower layer
LAYERS = (
    {"errors", "__version__"},
    {"jit", "extras", "provenance"},
    {"cluster", "model", "compiled_filters"},
    {"numerics", "tall_least_squares"},
    {"io"},
    {"sim"},
    {"ident"},
    {"controls"},
    {"stream", "export"},
    {"diagnose"},
    {"api", "day_summary"},
    {"fleet", "nodes"},
    {"cli"},
    {"__main__"},
)
LAYER = {name: i for i, names in enumerate(LAYERS) for name in names}


def _package(path: Path) -> str:
    return path.relative_to(ROOT).with_suffix("").parts[0]


def _imports(path: Path) -> list[tuple[int, str]]:
    found = []
    for node in ast.walk(ast.parse(path.read_text(), str(path))):
        if isinstance(node, ast.Import):
            found += [(node.lineno, a.name) for a in node.names]
        elif isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
            if node.module == "phid_ros":
                found += [(node.lineno, f"phid_ros.{a.name}") for a in node.names]
            else:
                found.append((node.lineno, node.module))
    return [(line, m.split(".")[1]) for line, m in found if m.startswith("phid_ros.")]


def test_every_package_has_a_layer():
    packages = {_package(p) for p in ROOT.rglob("*.py")} - {"__init__", "msg_schemas_data"}
    assert packages <= LAYER.keys(), packages - LAYER.keys()


def test_imports_go_downwards_only():
    upward = []
    for path in sorted(ROOT.rglob("*.py")):
        own = _package(path)
        if own not in LAYER:
            continue
        for line, target in _imports(path):
            if target != own and LAYER[target] >= LAYER[own]:
                upward.append(f"{path.relative_to(ROOT.parent)}:{line}: {own} imports {target}")
    assert not upward, "\n".join(upward)


# no import circle is left (issue 70): a new one fails below with its modules
KNOWN_CIRCLES: set[frozenset[str]] = set()


def _module(path: Path) -> str:
    parts = path.relative_to(ROOT).with_suffix("").parts
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def test_no_module_imports_itself_round_a_circle():
    """Modules importing each other (at the top or inside a function: either way one cannot be
    read without the other) were four circles: cli/report <-> cli/validate, cli/fleet <->
    cli/history_report, export/dyr_read -> formats -> record, and the stages'. A package's
    ``__init__`` re-exporting its modules is no circle."""
    modules = {_module(p): p for p in ROOT.rglob("*.py")}
    graph: dict[str, set[str]] = {m: set() for m in modules}
    for m, path in modules.items():
        for node in ast.walk(ast.parse(path.read_text(), str(path))):
            names = []
            if isinstance(node, ast.Import):
                names = [a.name for a in node.names]
            elif isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
                names = [node.module] + [f"{node.module}.{a.name}" for a in node.names]
            for n in names:
                target = n.removeprefix("phid_ros.")
                inside = modules.get(target, Path()).name == "__init__.py" and m.startswith(target + ".")
                if n.startswith("phid_ros.") and target in modules and target != m and not inside:
                    graph[m].add(target)
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    circles = []

    def visit(v: str) -> None:  # Tarjan's strongly connected components
        index[v] = low[v] = len(index)
        stack.append(v)
        for w in graph[v]:
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in stack:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            part = {stack.pop()}
            while v not in part:
                part.add(stack.pop())
            if len(part) > 1:
                circles.append(frozenset(part))

    for v in sorted(graph):
        if v not in index:
            visit(v)
    new = [sorted(c) for c in circles if c not in KNOWN_CIRCLES]
    assert not new, f"modules importing each other: {new}"


LONGEST_FUNCTION = 80  # lines, decorators left out: a longer one holds more than one job (issue 70)


def test_no_function_is_longer_than_a_screenful():
    long = [
        f"{path.relative_to(ROOT.parent)}:{node.lineno} {node.name} ({node.end_lineno - node.lineno + 1} lines)"
        for path in sorted(ROOT.rglob("*.py"))
        for node in ast.walk(ast.parse(path.read_text(), str(path)))
        if isinstance(node, ast.FunctionDef | ast.AsyncFunctionDef)
        and node.end_lineno is not None
        and node.end_lineno - node.lineno + 1 > LONGEST_FUNCTION
    ]
    assert not long, long

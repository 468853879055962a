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
    {"api"},
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

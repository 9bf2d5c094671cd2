"""The package's layers: no import cycle between its modules (TYPE_CHECKING imports included),
and each layer imports only the layers below it."""

import ast
import subprocess
import sys
from pathlib import Path

import redundancy

PACKAGE = Path(redundancy.__file__).parent
LAYERS = ["_core", "errors", "model", "resolution", "planning", "study", "viz", "cli", "__main__"]


def module_name(path: Path) -> str:
    parts = path.relative_to(PACKAGE.parent).with_suffix("").parts
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def imports() -> dict[str, set[str]]:
    """Every module of the package and the package modules it imports, anywhere in its text."""
    graph = {}
    for path in PACKAGE.rglob("*.py"):
        found = set()
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, ast.ImportFrom) and node.module:
                found.add(node.module)
            elif isinstance(node, ast.Import):
                found.update(alias.name for alias in node.names)
        graph[module_name(path)] = {n for n in found if n.startswith("redundancy.")}
    return graph


def layer(module: str) -> int:
    return LAYERS.index(module.split(".")[1])


def test_no_module_imports_itself_through_a_cycle():
    graph = imports()
    graph = {name: {n for n in targets if n in graph} for name, targets in graph.items()}
    visiting, done = set(), set()

    def visit(name, path):
        assert name not in visiting, f"import cycle: {' → '.join([*path, name])}"
        if name in done:
            return
        visiting.add(name)
        for target in graph[name]:
            visit(target, [*path, name])
        visiting.discard(name)
        done.add(name)

    for name in graph:
        visit(name, [])
    assert len(graph) > 20


def test_each_layer_imports_only_the_layers_below_it():
    for module, targets in imports().items():
        if module == "redundancy":
            continue  # the flat public API re-exports every layer
        for target in targets:
            assert layer(target) <= layer(module), f"{module} imports {target} from above"


def test_importing_the_package_loads_none_of_its_modules_until_a_name_is_used(tmp_path):
    """``import redundancy`` loads no library, not even typing or ast: the command handles
    Ctrl-C from its first moment. Every public name is imported when first used, and the
    public list is the type checkers' imports, each of which resolves."""
    code = (
        "import sys, redundancy\n"
        "print([m for m in ('numpy', 'pinocchio', 'typing', 'ast') if m in sys.modules])\n"
    )
    run = subprocess.run(
        [sys.executable, "-c", code], cwd=tmp_path, capture_output=True, text=True, check=True
    )
    assert run.stdout == "[]\n", run.stdout
    names = redundancy.__all__
    assert {"load_robot", "run_study", "Controller", "VELOCITY"} <= set(names)
    assert set(names) <= set(dir(redundancy))
    assert all(getattr(redundancy, name) is not None for name in names)

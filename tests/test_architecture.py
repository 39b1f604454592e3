"""The package's shape: layers that only look down, a light ``import sensorplan``, small modules.

The layers (docs/api.md, "Architecture"): foundations (errors, validation,
threads) -> model -> inference, design, io, acquisition -> verification, diagnosis ->
analysis -> plotting -> report -> cli.  A module may import its own
subpackage and lower layers only; peers on one layer do not import each
other.  The check parses every import statement, including the lazy ones
inside functions.
"""

import ast
import subprocess
import sys
from pathlib import Path

import pytest

PACKAGE = Path(__file__).resolve().parents[1] / "sensorplan"

LAYERS = {
    "_errors": 0, "examples": 0,
    "_validation": 0.5, "_threads": 0.5, "_allocator": 0.5, "_executors": 0.5, "_cache": 0.5, "verdict": 0.5,
    "model": 1,
    "detection": 1.5,
    "inference": 2, "design": 2, "io": 2, "acquisition": 2,
    "verification": 3, "diagnosis": 3,
    "analysis": 4,
    "plotting": 5,
    "report": 6,
    "cli": 7, "__main__": 8,
}

# third-party packages only the presentation layer (matplotlib), the design relaxation (cvxpy) or the
# executors (the optional Dask, imported lazily) may load
RESTRICTED = {"matplotlib": {"plotting", "report"}, "cvxpy": {"design"},
              "dask": {"_executors"}, "distributed": {"_executors"}}


def _modules():
    for path in sorted(PACKAGE.rglob("*.py")):
        rel = path.relative_to(PACKAGE).with_suffix("")
        yield path, rel.parts


def _top(parts):
    return parts[0] if parts[0] != "__init__" else None


def _imports(path, parts):
    """(line, top-level sensorplan unit or third-party package) of every import in ``path``."""
    tree = ast.parse(path.read_text(encoding="utf-8"))
    package = list(parts[:-1]) if parts[-1] != "__init__" else list(parts[:-1])
    for node in ast.walk(tree):
        if isinstance(node, ast.ImportFrom):
            if node.level:
                base = package[: len(package) - (node.level - 1)] if node.level > 1 else package
                target = base + (node.module.split(".") if node.module else [])
                if not target:  # "from . import x" at the top level: the imported names are units
                    for alias in node.names:  # a unit, or an attribute of the package root (layer 0)
                        yield node.lineno, ("sensorplan", alias.name if alias.name in LAYERS else "_errors")
                else:
                    yield node.lineno, ("sensorplan", target[0])
            elif node.module:
                root = node.module.split(".")
                yield node.lineno, ("sensorplan", root[1]) if root[0] == "sensorplan" and len(root) > 1 \
                    else (root[0], None)
        elif isinstance(node, ast.Import):
            for alias in node.names:
                root = alias.name.split(".")
                yield node.lineno, ("sensorplan", root[1]) if root[0] == "sensorplan" and len(root) > 1 \
                    else (root[0], None)


def test_every_unit_has_a_layer():
    units = {_top(parts) for _, parts in _modules()} - {None}
    assert units <= set(LAYERS), f"give these a layer: {sorted(units - set(LAYERS))}"


def test_layers_only_look_down():
    violations = []
    for path, parts in _modules():
        unit = _top(parts)
        if unit is None:
            continue  # sensorplan/__init__.py: the lazy public API
        for line, (root, target) in _imports(path, parts):
            if root == "sensorplan":
                if target == unit:
                    continue
                if LAYERS[target] >= LAYERS[unit]:
                    violations.append(f"{path.relative_to(PACKAGE.parent)}:{line} ({unit}, layer {LAYERS[unit]}) "
                                      f"imports {target} (layer {LAYERS[target]})")
            elif root in RESTRICTED and unit not in RESTRICTED[root]:
                violations.append(f"{path.relative_to(PACKAGE.parent)}:{line} imports {root}")
    assert not violations, "\n".join(violations)


def test_subpackages_say_what_they_own():
    for init in sorted(PACKAGE.glob("*/__init__.py")):
        doc = ast.get_docstring(ast.parse(init.read_text(encoding="utf-8"))) or ""
        if init.parent.name == "examples":
            continue
        assert "Owns" in doc and "May import" in doc, f"{init}: docstring must say what it owns and may import"


def test_import_sensorplan_is_light():
    code = ("import sys, sensorplan; sensorplan.Case; sensorplan.invert; sensorplan.recommend; "
            "sensorplan.verify_layouts; sensorplan.diagnose; sensorplan.design_study; "
            "bad = [m for m in ('matplotlib', 'cvxpy', 'dask', 'distributed') if m in sys.modules]; print(bad); sys.exit(bool(bad))")
    run = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, cwd=PACKAGE.parent)
    assert run.returncode == 0, run.stdout + run.stderr


@pytest.mark.parametrize("path", [p for p, _ in _modules()], ids=lambda p: str(p.relative_to(PACKAGE)))
def test_modules_are_small(path):
    n = len(path.read_text(encoding="utf-8").splitlines())
    assert n <= 420, f"{path.name} has {n} lines; split it (STYLE.md: past ~400 lines a module becomes a subpackage)"


def test_no_blanket_exception_handlers():
    found = []
    for path, _ in _modules():
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            if isinstance(node, ast.ExceptHandler):
                names = [] if node.type is None else [
                    getattr(t, "id", getattr(t, "attr", "")) for t in
                    (node.type.elts if isinstance(node.type, ast.Tuple) else [node.type])]
                if node.type is None or "Exception" in names:
                    found.append(f"{path.relative_to(PACKAGE.parent)}:{node.lineno}")
    assert not found, "blanket exception handlers: " + ", ".join(found)


def test_public_api_resolves_and_is_typed():
    import sensorplan

    for name in sensorplan.__all__:
        assert getattr(sensorplan, name) is not None, name
    assert (PACKAGE / "py.typed").exists()

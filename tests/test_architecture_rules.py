"""The house rules a reader relies on (docs/api.md, "Architecture"; STYLE.md, "Lessons from our own house").

* no import circle between the package's modules (registration goes through
  a family's registry module, never by an import at the bottom of a base);
* no private name imported across subpackages, and at most a handful
  between modules inside one;
* functions short enough to read in one screen (a few numerical kernels
  excepted);
* one cache type: no ``id()``- or ``tobytes()``-keyed memo outside
  ``sensorplan/_cache.py``.

Every import statement is parsed, including the lazy ones inside functions.
"""

import ast
from pathlib import Path

PACKAGE = Path(__file__).resolve().parents[1] / "sensorplan"
MAX_FUNCTION_LINES = 60
MAX_LONG_FUNCTIONS = 5
MAX_PRIVATE_IMPORTS = 5


def _modules():
    """(dotted name, path, is package) of every module of the package."""
    for path in sorted(PACKAGE.rglob("*.py")):
        parts = list(path.relative_to(PACKAGE.parent).with_suffix("").parts)
        package = parts[-1] == "__init__"
        if package:
            parts = parts[:-1]
        yield ".".join(parts), path, package


MODULES = {name: (path, package) for name, path, package in _modules()}


def _imported(name, package, node):
    """(target module, imported names) of an import node in module ``name``."""
    if isinstance(node, ast.ImportFrom):
        if node.level:
            base = name.split(".") if package else name.split(".")[:-1]
            base = base[: len(base) - (node.level - 1)]
            target = ".".join(base + (node.module.split(".") if node.module else []))
        else:
            target = node.module or ""
        return target, [alias.name for alias in node.names]
    return None, [alias.name for alias in node.names]


def _edges():
    """(importer, imported module, imported name or None) of every import of a package module."""
    for name, (path, package) in MODULES.items():
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            if isinstance(node, ast.ImportFrom):
                target, names = _imported(name, package, node)
                if not target.startswith("sensorplan"):
                    continue
                for alias in names:
                    sub = f"{target}.{alias}"
                    yield (name, sub, None) if sub in MODULES else (name, target, alias)
            elif isinstance(node, ast.Import):
                for alias in node.names:
                    if alias.name.startswith("sensorplan") and alias.name in MODULES:
                        yield name, alias.name, None


def _cycles(graph):
    """Strongly connected components of more than one module (Tarjan)."""
    index, low, stack, on, out, counter = {}, {}, [], set(), [], [0]

    def visit(v):
        index[v] = low[v] = counter[0]
        counter[0] += 1
        stack.append(v)
        on.add(v)
        for w in graph.get(v, ()):
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            component = []
            while True:
                w = stack.pop()
                on.discard(w)
                component.append(w)
                if w == v:
                    break
            if len(component) > 1:
                out.append(sorted(component))

    for v in sorted(graph):
        if v not in index:
            visit(v)
    return out


def test_no_import_circle():
    graph = {}
    for importer, target, _ in _edges():
        if target != importer and target in MODULES:
            graph.setdefault(importer, set()).add(target)
    assert not _cycles(graph), f"import circles: {_cycles(graph)}"


def _subpackage(module):
    parts = module.split(".")
    return parts[1] if len(parts) > 1 else ""


def test_private_names_stay_home():
    crossing, inside = [], []
    for importer, target, alias in _edges():
        if alias and alias.startswith("_") and not alias.startswith("__") and target != importer:
            line = f"{importer} imports {target}.{alias}"
            (inside if _subpackage(importer) == _subpackage(target) else crossing).append(line)
    assert not crossing, "private names imported across subpackages:\n" + "\n".join(crossing)
    assert len(inside) <= MAX_PRIVATE_IMPORTS, "private names imported between modules:\n" + "\n".join(inside)


def test_functions_fit_on_a_screen():
    long = []
    for name, (path, _) in MODULES.items():
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
                n = node.end_lineno - node.lineno + 1
                if n > MAX_FUNCTION_LINES:
                    long.append(f"{name}.{node.name} ({n} lines)")
    assert len(long) <= MAX_LONG_FUNCTIONS, "functions over 60 lines:\n" + "\n".join(sorted(long))


def test_one_cache_type():
    found = []
    for name, (path, _) in MODULES.items():
        if name == "sensorplan._cache":
            continue
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            if isinstance(node, ast.Call):
                func = node.func
                if (isinstance(func, ast.Name) and func.id == "id") or (
                        isinstance(func, ast.Attribute) and func.attr == "tobytes"):
                    found.append(f"{path.relative_to(PACKAGE.parent)}:{node.lineno}")
    assert not found, "id()/tobytes() keys outside sensorplan/_cache.py (use Cache / value_key): " + ", ".join(found)

"""The import rules and size limits of the code base, read from the source (README, "Architecture").

- ``psdm_casadi`` imports none of ``trajopt``, ``identification``, ``codegen``, except its command
  line (``psdm_casadi.cli``) and the demo (``psdm_casadi.demo``), which compose the packages;
- ``trajopt`` and ``identification`` import only ``psdm_casadi`` besides themselves; ``codegen``
  imports ``psdm_casadi`` and ``identification`` (it exports calibrated models); none of them
  imports the command line or the demo;
- inside ``identification``, the estimators (``data``, ``friction``, ``calibration``, ``diagnosis``)
  never import the virtual robot (``identification.virtual``);
- no module imports a private name (``_x``) of another module; tests may, to test a library helper directly, but
  never take one from another test module (shared test helpers live in the tests' data modules, public);
- no import cycles between modules, lazy (function-level) imports included;
- no library module over 500 lines, no library function over 80 lines of code (docstring excluded).
"""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
PACKAGES = ("psdm_casadi", "trajopt", "identification", "codegen")
COMPOSERS = ("psdm_casadi.cli", "psdm_casadi.demo")
ESTIMATORS = (
    "identification.data",
    "identification.friction",
    "identification.calibration",
    "identification.diagnosis",
    "identification.metrics",
)
ALLOWED = {
    "trajopt": ("trajopt", "psdm_casadi"),
    "identification": ("identification", "psdm_casadi"),
    "codegen": ("codegen", "identification", "psdm_casadi"),
}
MAX_MODULE_LINES = 500
MAX_FUNCTION_LINES = 80


def _module_name(path: Path) -> str:
    parts = list(path.relative_to(ROOT).with_suffix("").parts)
    if parts[-1] == "__init__":
        parts = parts[:-1]
    return ".".join(parts)


def _sources(*folders):
    for folder in folders:
        yield from sorted((ROOT / folder).rglob("*.py"))


LIBRARY = {_module_name(p): p for p in _sources(*PACKAGES)}


def _imports(path: Path):
    """(imported module, imported names, line) for every import of a file, relative ones resolved."""
    module = _module_name(path)
    package = module if path.name == "__init__.py" else module.rpartition(".")[0]
    for node in ast.walk(ast.parse(path.read_text(), str(path))):
        if isinstance(node, ast.Import):
            for alias in node.names:
                yield alias.name, [], node.lineno
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = package.split(".")[: len(package.split(".")) - (node.level - 1)]
                target = ".".join(base + ([node.module] if node.module else []))
            else:
                target = node.module
            yield target, [a.name for a in node.names], node.lineno


def _within(name: str, prefixes) -> bool:
    return any(name == p or name.startswith(p + ".") for p in prefixes)


def _resolved_targets(target: str, names):
    """The project modules an import statement reaches (``from pkg import module`` reaches the module)."""
    out = []
    for name in names:
        if f"{target}.{name}" in LIBRARY:
            out.append(f"{target}.{name}")
    if target in LIBRARY or not out:
        out.append(target)
    return out


def _violations_of_layers():
    bad = []
    for module, path in LIBRARY.items():
        top = module.split(".")[0]
        for target, _names, line in _imports(path):
            target_top = target.split(".")[0]
            if target_top not in PACKAGES:
                continue
            where = f"{path.relative_to(ROOT)}:{line} imports {target}"
            if top == "psdm_casadi":
                if target_top != "psdm_casadi" and not _within(module, COMPOSERS):
                    bad.append(where)
            elif target_top not in ALLOWED[top] or _within(target, COMPOSERS):
                bad.append(where)
            if _within(module, ESTIMATORS) and _within(target, ("identification.virtual",)):
                bad.append(where + " (an estimator imports the virtual robot)")
    return bad


def test_packages_import_only_what_the_layers_allow():
    assert _violations_of_layers() == []


def test_no_private_name_is_imported_across_modules():
    bad = []
    for path in _sources(*PACKAGES, "benchmarks", "examples"):
        for target, names, line in _imports(path):
            if target.split(".")[0] not in PACKAGES + ("bench_support",):
                continue
            private = [n for n in names if n.startswith("_") and not n.startswith("__")]
            private += [part for part in target.split(".") if part.startswith("_") and not part.startswith("__")]
            if private:
                bad.append(f"{path.relative_to(ROOT)}:{line} imports {private} from {target}")
    assert bad == []


def test_no_test_module_takes_a_private_name_of_another_test_module():
    bad = []
    for path in _sources("tests"):
        for target, names, line in _imports(path):
            if target.split(".")[0] != "tests":
                continue
            private = [n for n in names if n.startswith("_") and not n.startswith("__")]
            if private:
                bad.append(f"{path.relative_to(ROOT)}:{line} imports {private} from {target}")
    assert bad == []


def test_no_import_cycles():
    graph = {module: set() for module in LIBRARY}
    for module, path in LIBRARY.items():
        for target, names, _ in _imports(path):
            for reached in _resolved_targets(target, names):
                # importing a.b.c runs the packages a and a.b first: an edge to each
                parts = reached.split(".")
                for k in range(1, len(parts) + 1):
                    name = ".".join(parts[:k])
                    if name in LIBRARY and name != module and not module.startswith(name + "."):
                        graph[module].add(name)
    cycles = _cycles(graph)
    assert cycles == [], "import cycles: " + "; ".join(" -> ".join(c) for c in cycles)


def _cycles(graph):
    """Strongly connected components with more than one module (Tarjan), each as a sorted list."""
    index, low, stack, on_stack, out = {}, {}, [], set(), []
    counter = [0]

    def visit(v):
        index[v] = low[v] = counter[0]
        counter[0] += 1
        stack.append(v)
        on_stack.add(v)
        for w in sorted(graph[v]):
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
                out.append(sorted(component))

    for v in sorted(graph):
        if v not in index:
            visit(v)
    return out


def test_the_cycle_finder_finds_a_cycle():
    assert _cycles({"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}}) == [["a", "b", "c"]]
    assert _cycles({"a": {"b"}, "b": set()}) == []


@pytest.mark.parametrize("module", sorted(LIBRARY))
def test_modules_and_functions_stay_small(module):
    path = LIBRARY[module]
    text = path.read_text()
    assert text.count("\n") <= MAX_MODULE_LINES, f"{path.relative_to(ROOT)} has {text.count(chr(10))} lines"
    long = []
    for node in ast.walk(ast.parse(text)):
        if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
            body = node.body
            has_doc = (
                isinstance(body[0], ast.Expr)
                and isinstance(getattr(body[0], "value", None), ast.Constant)
                and isinstance(body[0].value.value, str)
            )
            start = (body[1].lineno if len(body) > 1 else node.end_lineno + 1) if has_doc else body[0].lineno
            lines = node.end_lineno - start + 1
            if lines > MAX_FUNCTION_LINES:
                long.append(f"{node.name} ({lines} lines)")
    assert long == [], f"{path.relative_to(ROOT)}: " + ", ".join(long)

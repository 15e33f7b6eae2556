"""The import layout, read from the sources (ast, nothing is imported): the core `ibm` imports
neither `baselines` nor `studies`, `baselines` does not import `studies`, and no module of any
package takes part in an import cycle. Imports inside functions count as well, and so do
importlib.import_module calls with a literal name. Exceptions are defined in ibm.exceptions only.

Run as a script (python tests/test_layout.py) to print the import graph and its cycles.
"""
from __future__ import annotations

import ast
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def _modules(package: str) -> dict[str, Path]:
    """Dotted module name -> source file, for every .py file of `package` (its __init__ as the package)."""
    base = ROOT / package
    modules = {}
    for path in sorted(base.rglob("*.py")):
        parts = (package, *path.relative_to(base).with_suffix("").parts)
        if parts[-1] == "__init__":
            parts = parts[:-1]
        modules[".".join(parts)] = path
    return modules


def _imports(module: str, path: Path) -> list[tuple[str, list[str]]]:
    """Every import of `module`, anywhere in its file (top level and inside functions), as
    (dotted name, names taken from it): `import a.b` -> ("a.b", []), `from a.b import c, d` ->
    ("a.b", ["c", "d"]); relative imports are resolved; import_module("a.b") -> ("a.b", [])."""
    is_package = path.name == "__init__.py"
    found = []
    for node in ast.walk(ast.parse(path.read_text(), filename=str(path))):
        if isinstance(node, ast.Import):
            found += [(alias.name, []) for alias in node.names]
        elif isinstance(node, ast.ImportFrom):
            base = node.module
            if node.level:
                parts = module.split(".")
                anchor = parts[: len(parts) - node.level + is_package]
                base = ".".join(anchor + ([node.module] if node.module else []))
            found.append((base, [alias.name for alias in node.names]))
        elif (isinstance(node, ast.Call) and node.args and isinstance(node.args[0], ast.Constant)
              and isinstance(node.args[0].value, str)
              and "import_module" in (getattr(node.func, "attr", None), getattr(node.func, "id", None))):
            found.append((node.args[0].value, []))
    return found


def _top_level_imports(package: str) -> dict[str, set[str]]:
    """Module of `package` -> the top-level packages it imports."""
    return {module: {name.split(".")[0] for name, _ in _imports(module, path)}
            for module, path in _modules(package).items()}


def import_graph(package: str) -> dict[str, set[str]]:
    """Module -> the modules of the same package it imports. `from a.b import c` counts a.b.c
    when that is a module, else a.b; a name that is no module counts its nearest enclosing one."""
    modules = _modules(package)

    def resolve(name: str) -> str:
        while name not in modules and "." in name:
            name = name.rsplit(".", 1)[0]
        return name

    graph = {}
    for module, path in modules.items():
        targets = set()
        for name, taken in _imports(module, path):
            if name.split(".")[0] != package:
                continue
            submodules = [f"{name}.{t}" for t in taken if f"{name}.{t}" in modules]
            targets.update(submodules)
            if not taken or len(submodules) < len(taken):     # something was taken from `name` itself
                targets.add(resolve(name))
        graph[module] = {t for t in targets if t in modules and t != module}
    return graph


def cycles(graph: dict[str, set[str]]) -> list[list[str]]:
    """One cycle (a -> ... -> a) for every strongly connected component that has one (Tarjan)."""
    index, low, stack, on_stack, components = {}, {}, [], set(), []

    def visit(node: str) -> None:
        index[node] = low[node] = len(index)
        stack.append(node)
        on_stack.add(node)
        for target in sorted(graph.get(node, ())):
            if target not in index:
                visit(target)
                low[node] = min(low[node], low[target])
            elif target in on_stack:
                low[node] = min(low[node], index[target])
        if low[node] == index[node]:
            component = []
            while True:
                member = stack.pop()
                on_stack.discard(member)
                component.append(member)
                if member == node:
                    break
            if len(component) > 1 or node in graph.get(node, ()):
                components.append(set(component))

    for node in sorted(graph):
        if node not in index:
            visit(node)
    return [_cycle_in(graph, component) for component in components]


def _cycle_in(graph: dict[str, set[str]], component: set[str]) -> list[str]:
    """A shortest cycle through the first member of `component`, as [a, b, ..., a]."""
    start = min(component)
    paths, seen = [[start]], {start}
    while paths:
        path = paths.pop(0)
        for target in sorted(graph[path[-1]] & component):
            if target == start:
                return path + [start]
            if target not in seen:
                seen.add(target)
                paths.append(path + [target])
    raise AssertionError("a strongly connected component without a cycle")


def test_the_core_imports_neither_baselines_nor_studies():
    offending = {module: sorted(names & {"baselines", "studies"})
                 for module, names in _top_level_imports("ibm").items() if names & {"baselines", "studies"}}
    assert not offending, f"ibm must not import baselines or studies: {offending}"


def test_baselines_do_not_import_studies():
    offending = sorted(module for module, names in _top_level_imports("baselines").items() if "studies" in names)
    assert not offending, f"baselines must not import studies: {offending}"


PACKAGES = ("ibm", "baselines", "studies")


def whole_graph() -> dict[str, set[str]]:
    """Module -> the modules it imports, over every package (studies -> baselines -> ibm)."""
    graph = {}
    for package in PACKAGES:
        graph.update(import_graph(package))
    for module, path in [(m, p) for package in PACKAGES for m, p in _modules(package).items()]:
        for name, taken in _imports(module, path):
            if name.split(".")[0] in PACKAGES and name.split(".")[0] != module.split(".")[0]:
                candidates = [f"{name}.{t}" for t in taken if f"{name}.{t}" in graph] or [name]
                graph[module].update(c for c in candidates if c in graph)
    return graph


def test_no_module_takes_part_in_an_import_cycle():
    found = cycles(whole_graph())
    assert not found, "import cycles: " + "; ".join(" -> ".join(c) for c in found)


def test_exceptions_are_defined_in_one_module():
    elsewhere = []
    for package in PACKAGES:
        for module, path in _modules(package).items():
            if module == "ibm.exceptions":
                continue
            for node in ast.walk(ast.parse(path.read_text())):
                if isinstance(node, ast.ClassDef) and any(
                        getattr(base, "id", getattr(base, "attr", "")).endswith(("Error", "Exception", "Exit",
                                                                                  "Lost", "Failure", "Busy"))
                        for base in node.bases):
                    elsewhere.append(f"{module}.{node.name}")
    assert not elsewhere, f"exceptions outside ibm.exceptions: {elsewhere}"


# What a module may import inside a function: a library that is optional or slow to import (about a
# second each) and that only some paths need, or a module of this project that pulls one in.
LAZY = {
    "sympy": "symbolic fields, for the manufactured and file-defined problems only",
    "matplotlib": "figures", "mpl_toolkits": "figures", "PIL": "figures",
    "distributed": "parallel studies", "meshio": "VTK output",
    "pypardiso": "an optional solver backend", "pyamg": "an optional solver backend",
    "studies.report": "the report (pandas, jinja2, matplotlib): not needed to solve a case",
    "bokeh": "BokehJS for a page with interactive figures (0.2 s to import): only when a page has them",
    "studies.run.store": "the results store (pandas, pyarrow): not needed to solve a case",
    "studies.run.runner": "the study runner (pandas, pyarrow): not needed to solve a case",
}
# Each size of the scaling study runs in a fresh process that imports only what it measures.
LAZY_MODULES = {"studies.run.scaling"}


def _inner_imports(path: Path) -> list[tuple[int, str]]:
    """(line, dotted name) of every import inside a function of `path`."""
    found = []
    for function in ast.walk(ast.parse(path.read_text(), filename=str(path))):
        if isinstance(function, (ast.FunctionDef, ast.AsyncFunctionDef)):
            for node in ast.walk(function):
                if isinstance(node, ast.Import):
                    found += [(node.lineno, alias.name) for alias in node.names]
                elif isinstance(node, ast.ImportFrom):
                    found.append((node.lineno, node.module or ""))
    return found


def _eager(path: Path) -> list[str]:
    """The imports inside functions of `path` that LAZY does not allow, as 'line: name'."""
    return [f"{line}: {name}" for line, name in _inner_imports(path)
            if not any(name == lazy or name.startswith(lazy + ".") for lazy in LAZY)]


def test_imports_inside_functions_are_only_of_slow_or_optional_libraries():
    offending = [f"{path.relative_to(ROOT)}:{where}" for package in PACKAGES
                 for module, path in _modules(package).items() if module not in LAZY_MODULES
                 for where in _eager(path)]
    assert not offending, "imports inside functions (move them to the top): " + "; ".join(offending)


def test_the_inner_import_check_fails_on_one(tmp_path):
    probe = tmp_path / "probe.py"
    probe.write_text("import numpy\n\ndef f():\n    import json\n    from studies.report import page\n"
                     "    import sympy.abc\n")
    assert _eager(probe) == ["4: json"]


def test_the_cycle_check_sees_imports_inside_functions():
    graph = import_graph("studies")
    assert "studies.report.page" in graph["studies.run.runner"]          # the lazy import in run_study
    assert "studies.run.store" in graph["studies.report.page"] and "studies.run.store" in graph["studies.run.runner"]
    assert cycles({"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}}) == [["a", "b", "c", "a"]]


if __name__ == "__main__":
    graph = whole_graph()
    for module in sorted(graph):
        print(f"{module} -> {', '.join(sorted(graph[module])) or '-'}")
    found = cycles(graph)
    print("cycles:", "; ".join(" -> ".join(c) for c in found) if found else "none")

"""The package's imports go one way (docs/architecture.md): read from the source with `ast`
(imports inside functions count too), they must form no circle, import no private name
from another module, and keep each package to the packages below it — the data model
imports no stepper, remap, output or study."""

from __future__ import annotations

import ast
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
PACKAGE = "ale_xfem"

# Each part of the code and the parts it may import (the data flow of docs/architecture.md:
# scene → problem → Lagrange step (pure | mixed cells) → remap → outputs).  `forms` is the
# UFL forms beside the package.
MAY_IMPORT = {
    "geometry": set(),
    "eos": set(),
    "exact": set(),
    "forms": set(),
    "scene": {"eos", "geometry"},
    "model": {"eos", "geometry"},
    "lagrange": {"model", "eos"},
    "mixed": {"model", "lagrange", "forms", "geometry", "eos"},
    "problem": {"scene", "model", "exact", "geometry", "eos", "mixed"},
    "remap": {"model", "geometry"},
    "parallel": {"model", "lagrange", "mixed", "remap", "scene", "forms"},
    "run": {"problem", "model", "lagrange", "mixed", "remap", "parallel"},
    "output": {"run", "problem", "model", "geometry", "scene"},
    "studies": {"run", "problem", "scene", "output", "model", "exact", "eos", "geometry", "mixed", "forms"},
    "cli": {"run", "problem", "scene", "output", "studies", "parallel"},
}
STEPPERS = {"lagrange", "mixed", "remap", "parallel", "run", "output", "studies", "cli"}


def module_name(path: Path) -> str:
    parts = list(path.relative_to(ROOT).with_suffix("").parts)
    if parts[-1] == "__init__":
        parts.pop()
    return ".".join(parts)


def source_modules() -> dict[str, Path]:
    files = list((ROOT / PACKAGE).rglob("*.py")) + list((ROOT / "forms").rglob("*.py"))
    return {module_name(p): p for p in files}


def imports_of(path: Path, name: str, modules: dict[str, Path]) -> list[tuple[str, str]]:
    """(imported module, imported name or "") of every import of the project's own modules
    in a file, wherever it stands."""
    package = name if path.name == "__init__.py" else name.rpartition(".")[0]
    found = []
    for node in ast.walk(ast.parse(path.read_text(), str(path))):
        if isinstance(node, ast.Import):
            found += [(alias.name, "") for alias in node.names]
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:  # relative import
                anchor = package.split(".")[: len(package.split(".")) - node.level + 1]
                base = ".".join(anchor + ([base] if base else []))
            for alias in node.names:
                submodule = f"{base}.{alias.name}"
                # `from package import module` imports that module
                found.append((submodule, "") if submodule in modules else (base, alias.name))
    return [(module, item) for module, item in found if module.split(".")[0] in (PACKAGE, "forms")]


def import_graph() -> tuple[dict[str, set[str]], list[tuple[str, str, str]]]:
    """Module → modules it imports; and (importer, module, name) of every import."""
    modules = source_modules()
    graph, imports = {}, []
    for name, path in modules.items():
        graph[name] = set()
        for module, item in imports_of(path, name, modules):
            while module not in modules and "." in module:  # an attribute of a module
                module = module.rpartition(".")[0]
            if module != name:
                graph[name].add(module)
            imports.append((name, module, item))
    return graph, imports


def part(module: str) -> str:
    """The part of the code a module belongs to: its subpackage, or run / cli / forms."""
    pieces = module.split(".")
    if pieces[0] == "forms":
        return "forms"
    return pieces[1] if len(pieces) > 1 else "package"


def circles(graph: dict[str, set[str]]) -> list[list[str]]:
    """The strongly connected components with more than one member (Tarjan)."""
    index, low, stack, on_stack, found, counter = {}, {}, [], set(), [], [0]

    def visit(v):
        index[v] = low[v] = counter[0]
        counter[0] += 1
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
    return found


def part_graph(graph: dict[str, set[str]]) -> dict[str, set[str]]:
    parts: dict[str, set[str]] = {}
    for module, targets in graph.items():
        edges = parts.setdefault(part(module), set())
        edges.update(part(t) for t in targets if part(t) != part(module))
    return parts


def test_no_module_imports_in_a_circle():
    graph, _ = import_graph()
    assert not circles(graph), f"import circles: {circles(graph)}"


def test_no_part_of_the_code_imports_in_a_circle():
    parts = part_graph(import_graph()[0])
    assert not circles(parts), f"circles between parts of the code: {circles(parts)}"


def test_no_private_name_is_imported_from_another_module():
    _, imports = import_graph()
    private = [f"{importer} imports {item} from {module}" for importer, module, item in imports
               if item.startswith("_") or any(p.startswith("_") for p in module.split(".")[1:])]
    assert not private, "; ".join(private)


def test_each_part_imports_only_the_parts_below_it():
    graph, _ = import_graph()
    known = set(MAY_IMPORT) | {"package"}
    wrong = []
    for module, targets in sorted(graph.items()):
        here = part(module)
        assert here in known, f"{module}: part '{here}' is not in MAY_IMPORT (docs/architecture.md)"
        for target in sorted(targets):
            there = part(target)
            if there != here and there not in MAY_IMPORT.get(here, set()) | {"package"}:
                wrong.append(f"{module} imports {target}")
    assert not wrong, "; ".join(wrong)


def reachable(graph: dict[str, set[str]], start: str) -> set[str]:
    seen, todo = set(), [start]
    while todo:
        for target in graph.get(todo.pop(), ()):
            if target not in seen:
                seen.add(target)
                todo.append(target)
    return seen


def test_the_data_model_and_the_problem_load_no_stepper():
    """Neither the data model nor the building of a problem reaches, through any chain of
    imports, the Lagrange step, the remap, the time loop or the outputs (the problem starts
    its mixed cells at pressure equilibrium with ale_xfem.mixed.equilibrium, which stands on
    the model alone, and gives 2D enriched mixed cells their condensed nodal masses with
    ale_xfem.mixed.cut_cells_2d, the cut geometry, which stands on the model and the forms'
    quadrature)."""
    graph, _ = import_graph()
    starts = [m for m in graph if part(m) in ("model", "geometry", "eos", "exact", "scene", "problem")]
    assert any(part(m) == "model" for m in starts) and any(part(m) == "problem" for m in starts)
    leaks = [f"{m} reaches {t}" for m in sorted(starts) for t in sorted(reachable(graph, m))
             if part(t) in STEPPERS and t not in ("ale_xfem.mixed.equilibrium", "ale_xfem.mixed.cut_cells_2d")]
    assert not leaks, "; ".join(leaks[:8])


def test_the_checks_see_a_circle_and_a_private_import(tmp_path):
    """The walker is not blind: a circle of two modules and a private import are found."""
    assert circles({"a": {"b"}, "b": {"a"}, "c": {"a"}}) == [["a", "b"]]
    assert circles({"a": {"b"}, "b": set()}) == []
    source = tmp_path / "m.py"
    source.write_text("def f():\n    from ale_xfem.model.state import _hidden\n")
    assert imports_of(source, "ale_xfem.m", {"ale_xfem.model.state": source}) == [
        ("ale_xfem.model.state", "_hidden")]

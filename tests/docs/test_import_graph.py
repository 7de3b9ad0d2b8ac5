"""The imports of the add-on, the command-line scripts, the benchmarks and the kernel's binding form no circle: each module
imports only modules below it. Imports inside functions count (a lazy import is still a dependency). No
Blender: the sources are parsed, not imported."""

import ast
import re
from pathlib import Path

from helpers import REPOSITORY


def python_modules(folder: Path, package: str | None) -> dict[str, Path]:
    """{module name: file} of the ``*.py`` under ``folder``: ``package.sub.module`` when the folder is imported as
    a package, else the file's stem (a scripts folder put on ``sys.path``)."""
    modules = {}
    for path in sorted(folder.rglob("*.py")):
        if "__pycache__" in path.parts:
            continue
        parts = list(path.relative_to(folder).with_suffix("").parts)
        if parts[-1] == "__init__":
            parts = parts[:-1]
        if package is None and len(parts) != 1:
            continue
        modules[".".join(([package] if package else []) + parts)] = path
    return modules


def python_imports(modules: dict[str, Path]) -> dict[str, set[str]]:
    """{module: the modules of ``modules`` it imports}, relative imports resolved."""

    def known(name: str) -> str | None:
        while name and name not in modules:
            name = name.rpartition(".")[0]
        return name or None

    graph = {}
    for name, path in modules.items():
        package = name if path.name == "__init__.py" else name.rpartition(".")[0]
        imported = set()
        for node in ast.walk(ast.parse(path.read_text(), str(path))):
            if isinstance(node, ast.Import):
                imported.update(known(alias.name) for alias in node.names)
            elif isinstance(node, ast.ImportFrom):
                base = node.module or ""
                if node.level:
                    anchor = package
                    for _ in range(node.level - 1):
                        anchor = anchor.rpartition(".")[0]
                    base = ".".join(filter(None, [anchor, node.module]))
                for alias in node.names:
                    full = f"{base}.{alias.name}"
                    imported.add(full if full in modules else known(base))
        graph[name] = {other for other in imported if other and other != name}
    return graph


def rust_uses(source: Path) -> dict[str, set[str]]:
    """{module: the crate's modules it uses} of a crate whose modules are the ``*.rs`` files of ``source``
    (``crate::name`` paths)."""
    modules = {path.stem for path in source.glob("*.rs")} - {"lib"}
    return {
        path.stem: set(re.findall(r"\bcrate::(\w+)", path.read_text())) & modules - {path.stem}
        for path in source.glob("*.rs")
        if path.stem != "lib"
    }


def circles(graph: dict[str, set[str]]) -> list[list[str]]:
    """The graph's strongly connected components of more than one module (Tarjan's algorithm, iterative)."""
    index, low, on_stack, stack, found = {}, {}, set(), [], []
    for root in graph:
        if root in index:
            continue
        work = [(root, iter(sorted(graph[root])))]
        index[root] = low[root] = len(index)
        stack.append(root)
        on_stack.add(root)
        while work:
            node, children = work[-1]
            child = next(children, None)
            if child is not None:
                if child not in index:
                    index[child] = low[child] = len(index)
                    stack.append(child)
                    on_stack.add(child)
                    work.append((child, iter(sorted(graph.get(child, ())))))
                elif child in on_stack:
                    low[node] = min(low[node], index[child])
                continue
            work.pop()
            if work:
                low[work[-1][0]] = min(low[work[-1][0]], low[node])
            if low[node] == index[node]:
                component = []
                while True:
                    member = stack.pop()
                    on_stack.discard(member)
                    component.append(member)
                    if member == node:
                        break
                if len(component) > 1:
                    found.append(sorted(component))
    return found


def test_the_circle_finder_finds_a_circle_and_passes_a_chain():
    assert circles({"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}}) == [["a", "b", "c"]]
    assert circles({"a": {"b"}, "b": {"c"}, "c": set()}) == []


def test_the_addon_imports_no_circle():
    graph = python_imports(python_modules(REPOSITORY / "addon" / "springwrap", "springwrap"))
    assert "springwrap.blender.follow" in graph["springwrap.properties"]
    assert "springwrap.core.defaults" in graph["springwrap.blender.follow"]
    assert circles(graph) == []


def test_the_scripts_import_no_circle():
    graph = python_imports(python_modules(REPOSITORY / "blender_scripts", None))
    assert "retarget_batch" in graph["retarget"]
    assert circles(graph) == []


def test_the_benchmarks_import_no_circle():
    graph = python_imports(python_modules(REPOSITORY / "benchmarks", "benchmarks"))
    assert "benchmarks.retarget.baselines" in graph["benchmarks.retarget.springwrap_methods"]
    assert circles(graph) == []


def test_the_bindings_modules_use_no_circle():
    graph = rust_uses(REPOSITORY / "rust_core" / "python" / "src")
    assert "errors" in graph["features"]
    assert circles(graph) == []

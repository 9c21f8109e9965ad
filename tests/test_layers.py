"""The packages import one way (issue 24, docs/layout.md): vibfree and app over optim, runtime and models; optim
over models and runtime; runtime (the process plumbing) over models.errors only; models over none of them.

Read from the source (every import, at module level or in a function), so a lazy import counts too."""

from __future__ import annotations

import ast
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
PACKAGES = ("vibfree", "app", "optim", "runtime", "models")
ALLOWED = {  # the service's packages each may import (besides itself)
    "vibfree": {"app", "optim", "runtime", "models"},
    "app": {"optim", "runtime", "models"},
    "optim": {"models", "runtime"},
    "runtime": {"models.errors"},
    "models": set(),
}
RUNTIME_THIRD_PARTY = {"numpy", "distributed"}  # distributed: runtime.dask, imported when a client connects


def _imports(package: str) -> list[tuple[str, str]]:
    """(file, module) of every absolute import in the package's source."""
    found = []
    for path in sorted((ROOT / package).rglob("*.py")):
        for node in ast.walk(ast.parse(path.read_text(), str(path))):
            if isinstance(node, ast.Import):
                found += [(str(path.relative_to(ROOT)), alias.name) for alias in node.names]
            elif isinstance(node, ast.ImportFrom) and node.level == 0 and node.module is not None:
                if node.module in PACKAGES:  # from runtime import cache: the submodule is what is imported
                    found += [(str(path.relative_to(ROOT)), f"{node.module}.{alias.name}") for alias in node.names]
                else:
                    found.append((str(path.relative_to(ROOT)), node.module))
    return found


def _allowed(module: str, allowed: set[str]) -> bool:
    return any(module == name or module.startswith(name + ".") for name in allowed)


@pytest.mark.parametrize("package", PACKAGES)
def test_a_package_imports_only_the_layers_below_it(package: str) -> None:
    wrong = [
        (path, module)
        for path, module in _imports(package)
        if module.split(".")[0] in PACKAGES
        and module.split(".")[0] != package
        and not _allowed(module, ALLOWED[package])
    ]
    assert not wrong, f"{package} may import {sorted(ALLOWED[package])} of the service's packages: {wrong}"


def test_runtime_needs_only_the_standard_library_numpy_and_models_errors() -> None:
    outside = [
        (path, module)
        for path, module in _imports("runtime")
        if module.split(".")[0] not in {*PACKAGES, *sys.stdlib_module_names, *RUNTIME_THIRD_PARTY}
    ]
    assert not outside, outside


def test_no_router_is_imported_outside_the_app_factory() -> None:
    """Routers are HTTP only (issue 24): the services, the Python API and the warm-up import none, and no router
    imports another; only the app factory (app/main.py) mounts them. A string import (importlib) counts too."""
    offenders = {
        (name, module)
        for package in PACKAGES
        for name, module in _imports(package)
        if module.startswith("app.routers") and name != "app/main.py"
    }
    for package in PACKAGES:
        for path in (ROOT / package).rglob("*.py"):
            if '"app.routers.' in path.read_text():
                offenders.add((str(path.relative_to(ROOT)), "app.routers (by string)"))
    assert sorted(offenders) == []


def test_no_module_imports_one_that_imports_it_back() -> None:
    """No import circle among the service's modules (issue 24: optim.family reached the registry through a lazy
    __getattr__, app.problems -> responses -> schemas -> problems through a set filled at import); a lazy import
    counts too."""
    modules = {}
    for package in PACKAGES:
        for path in (ROOT / package).rglob("*.py"):
            name = ".".join(path.relative_to(ROOT).with_suffix("").parts).removesuffix(".__init__")
            modules[name] = path
    graph: dict[str, set[str]] = {name: set() for name in modules}
    for name, path in modules.items():
        for node in ast.walk(ast.parse(path.read_text())):
            targets = []
            if isinstance(node, ast.Import):
                targets = [alias.name for alias in node.names]
            elif isinstance(node, ast.ImportFrom) and node.level == 0 and node.module is not None:
                targets = [node.module, *(f"{node.module}.{alias.name}" for alias in node.names)]
            for target in targets:
                while target and target not in modules:
                    target = target.rpartition(".")[0]
                if target and target != name:
                    graph[name].add(target)  # a name from a package is an edge to its __init__ (not to a parent
                    # of a submodule: a.b.c imported by path needs only what a/__init__ already defines when it runs)
    cycles = [m for m in graph if _reaches(graph, m, m)]
    assert cycles == []


def _reaches(graph: dict[str, set[str]], start: str, goal: str) -> bool:
    seen: set[str] = set()
    todo = list(graph[start])
    while todo:
        node = todo.pop()
        if node == goal:
            return True
        if node not in seen:
            seen.add(node)
            todo.extend(graph[node])
    return False


@pytest.mark.parametrize("package", ["optim", "runtime", "models"])
def test_below_the_app_nothing_imports_the_web_stack(package: str) -> None:
    """optim returns typed results and knows no URL (issue 24): fastapi, starlette and pydantic's HTTP side stay in
    app (and the runtime, plumbing for any caller, imports none of them either)."""
    web = ("fastapi", "starlette", "uvicorn", "httpx")
    found = [(name, module) for name, module in _imports(package) if module.split(".")[0] in web]
    assert found == []


def test_every_class_and_module_has_one_name_and_stays_readable() -> None:
    # Issue 24: distinct things have distinct names (a Problem, a Settings, a Metrics each meant two things), and
    # no module is over 450 lines. Private names (a leading underscore) are each module's own business.
    defined: dict[str, list[str]] = {}
    long: list[str] = []
    for package in PACKAGES:
        for path in sorted((ROOT / package).rglob("*.py")):
            source = path.read_text()
            if source.count("\n") > 450:
                long.append(f"{path.relative_to(ROOT)}: {source.count(chr(10))} lines")
            for node in ast.parse(source).body:
                if isinstance(node, ast.ClassDef) and not node.name.startswith("_"):
                    defined.setdefault(node.name, []).append(str(path.relative_to(ROOT)))
    for folder in ("tests", "bench", "scripts"):
        for path in sorted((ROOT / folder).rglob("*.py")):
            lines = path.read_text().count("\n")
            if lines > 450:
                long.append(f"{path.relative_to(ROOT)}: {lines} lines")
    assert {name: paths for name, paths in defined.items() if len(paths) > 1} == {}
    assert long == []

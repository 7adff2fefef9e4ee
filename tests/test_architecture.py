"""The package's layout: no import cycle, and every stage imports only stages before it.

Every ``import`` and ``from ... import`` in every module is read with :mod:`ast`, at module level
and inside functions, ``TYPE_CHECKING`` blocks included. ``python -m pytest tests/test_architecture.py``
is the check; ``python tests/test_architecture.py`` prints the graph's cycles and order breaks.
"""

from __future__ import annotations

import ast
import sys
from pathlib import Path

import pytest

import energy_margin

PACKAGE = Path(energy_margin.__file__).parent

#: The stages in the order data flows. Modules outside them (errors, _moved, the package
#: ``__init__``) are foundations every stage may import, and they import no stage.
STAGES = (
    "runs",
    "world",
    "sim",
    "tasks",
    "data",
    "planning",
    "analysis",
    "evaluation",
    "robustness",
    "learning",
    "control",
    "report",
    "cli",
)
FOUNDATIONS = (
    "energy_margin",
    "energy_margin.errors",
    "energy_margin._moved",
    "energy_margin._version",
    "energy_margin.__main__",
)


def module_names() -> dict[str, Path]:
    """Every module of the package by dotted name."""
    names: dict[str, Path] = {}
    for path in PACKAGE.rglob("*.py"):
        parts = path.relative_to(PACKAGE.parent).with_suffix("").parts
        if parts[-1] == "__init__":
            parts = parts[:-1]
        names[".".join(parts)] = path
    return names


def imports_of(name: str, path: Path, modules: dict[str, Path]) -> set[str]:
    """The package's modules that module ``name`` imports (a package's submodule when named)."""
    is_package = path.name == "__init__.py"
    found: set[str] = set()
    for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
        if isinstance(node, ast.Import):
            targets = [alias.name for alias in node.names]
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:
                anchor = name.split(".") if is_package else name.split(".")[:-1]
                anchor = anchor[: len(anchor) - node.level + 1]
                base = ".".join([*anchor, base] if base else anchor)
            targets = [f"{base}.{alias.name}" if f"{base}.{alias.name}" in modules else base for alias in node.names]
        else:
            continue
        for target in targets:
            # `import a.b.c` imports a, a.b and a.b.c; the edge that matters is the deepest module.
            while target and target not in modules:
                target = target.rpartition(".")[0]
            if target and target != name and target.startswith("energy_margin"):
                found.add(target)
    return found


def import_graph() -> dict[str, set[str]]:
    """Module -> the package's modules it imports."""
    modules = module_names()
    graph = {name: imports_of(name, path, modules) for name, path in modules.items()}
    # A package's __init__ runs before its submodules: an edge from a submodule to its own
    # package (or an ancestor) is the parent-package import, not a dependency on the names in it.
    for name, targets in graph.items():
        graph[name] = {t for t in targets if not name.startswith(t + ".")}
    return graph


def cycles(graph: dict[str, set[str]]) -> list[list[str]]:
    """Strongly connected components with more than one module (Tarjan)."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on_stack: set[str] = set()
    found: list[list[str]] = []
    counter = [0]
    sys.setrecursionlimit(max(sys.getrecursionlimit(), 10_000))

    def visit(node: str) -> None:
        index[node] = low[node] = counter[0]
        counter[0] += 1
        stack.append(node)
        on_stack.add(node)
        for target in graph.get(node, ()):
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
            if len(component) > 1:
                found.append(sorted(component))

    for node in sorted(graph):
        if node not in index:
            visit(node)
    return found


def stage_of(name: str) -> int | None:
    """Position of the module's stage in :data:`STAGES`, ``None`` for a foundation."""
    parts = name.split(".")
    if len(parts) < 2 or parts[1] not in STAGES:
        return None
    return STAGES.index(parts[1])


def order_breaks(graph: dict[str, set[str]]) -> list[str]:
    """Imports of a later stage by an earlier one, and of any stage by a foundation."""
    breaks = []
    for name, targets in sorted(graph.items()):
        own = stage_of(name)
        for target in sorted(targets):
            other = stage_of(target)
            if other is None:
                continue
            if own is None and name not in ("energy_margin", "energy_margin.__main__"):
                breaks.append(f"{name} (a foundation) imports {target}")
            elif own is not None and other > own:
                breaks.append(f"{name} ({STAGES[own]}) imports {target} ({STAGES[other]})")
    return breaks


def test_every_module_is_in_a_stage_or_a_foundation() -> None:
    strays = [name for name in module_names() if stage_of(name) is None and name not in FOUNDATIONS]
    assert strays == []


def test_the_package_has_no_import_cycle() -> None:
    assert cycles(import_graph()) == []


def test_stages_import_only_earlier_stages() -> None:
    assert order_breaks(import_graph()) == []


def test_the_walk_sees_imports_inside_functions_and_type_checking_blocks(tmp_path: Path) -> None:
    source = (
        "from typing import TYPE_CHECKING\n"
        "if TYPE_CHECKING:\n    from energy_margin.report.html import write_report\n"
        "def f():\n    from energy_margin.cli import analyze\n"
    )
    path = tmp_path / "probe.py"
    path.write_text(source)
    modules = module_names()
    found = imports_of("energy_margin.world.probe", path, modules)
    assert found == {"energy_margin.report.html", "energy_margin.cli.analyze"}


def test_a_cycle_is_found() -> None:
    assert cycles({"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}}) == [["a", "b", "c"]]
    assert order_breaks({"energy_margin.world.scene": {"energy_margin.cli.app"}}) != []


@pytest.mark.parametrize(
    ("old", "name"),
    [
        ("energy_margin.dataset", "load_dataset"),
        ("energy_margin.dataset", "SCORES_FILE"),
        ("energy_margin.analysis", "load_scores"),
        ("energy_margin.analysis", "AnalyzerConfig"),
        ("energy_margin.scene", "Scene"),
        ("energy_margin.state", "FrameState"),
        ("energy_margin.ellipsoid", "min_volume_ellipsoid"),
        ("energy_margin.energy", "make_cost_model"),
        ("energy_margin.scores", "likelihood"),
        ("energy_margin.executors", "make_executor"),
        ("energy_margin.validation", "check_dataset"),
        ("energy_margin.reference", "import_reference"),
        ("energy_margin.perturb", "perturb_dataset"),
        ("energy_margin.robustness", "compare_perturbed"),
        ("energy_margin.baselines", "distance_scores"),
        ("energy_margin.budget", "budget_sweep"),
        ("energy_margin.plots", "frame_figure"),
        ("energy_margin.report", "write_report"),
        ("energy_margin.reproduce", "ReproduceConfig"),
        ("energy_margin.reproduce", "PAPER_TABLE_I"),
        ("energy_margin.io", "atomic_write_text"),
    ],
)
def test_old_import_paths_still_resolve_with_a_warning(old: str, name: str) -> None:
    import importlib

    with pytest.warns(DeprecationWarning, match="moved to"):
        module = importlib.import_module(old)
        value = getattr(module, name)
    assert value is not None
    assert callable(value) or isinstance(value, dict | str | tuple)


def test_an_unknown_name_on_an_old_path_is_an_attribute_error() -> None:
    import importlib
    import warnings

    with warnings.catch_warnings():
        warnings.simplefilter("ignore", DeprecationWarning)
        module = importlib.import_module("energy_margin.dataset")
    with pytest.raises(AttributeError):
        module.no_such_name  # noqa: B018


def test_the_public_api_is_where_it_was() -> None:
    from energy_margin.tasks import register_task

    for name in (
        "analyze",
        "analyze_frame",
        "AnalyzerConfig",
        "generate_dataset",
        "load_dataset",
        "evaluate",
        "min_volume_ellipsoid",
        "perturb_dataset",
        "compare_perturbed",
    ):
        assert callable(getattr(energy_margin, name)), name
    assert callable(register_task)


if __name__ == "__main__":
    graph = import_graph()
    print(f"{len(graph)} modules, {sum(len(t) for t in graph.values())} imports")
    print("cycles:", cycles(graph) or "none")
    print("order breaks:", order_breaks(graph) or "none")

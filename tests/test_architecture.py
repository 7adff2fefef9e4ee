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
from energy_margin._stages import STAGES

PACKAGE = Path(energy_margin.__file__).parent

#: The stages in the order data flows. Modules outside them (errors, compat, _moved, the package
#: ``__init__``) are foundations every stage may import, and they import no stage.
FOUNDATIONS = (
    "energy_margin",
    "energy_margin.errors",
    "energy_margin.compat",
    "energy_margin._moved",
    "energy_margin._lazy",
    "energy_margin._renamed",
    "energy_margin._stages",
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
        ("energy_margin.evaluation.design_search", "design_search"),
        ("energy_margin.evaluation.design_space", "parse_search_param"),
        ("energy_margin.evaluation.designs", "design_grid"),
        ("energy_margin.evaluation.sweep", "design_sweep"),
        ("energy_margin.control.verification", "EpisodeVerifier"),
        ("energy_margin.evaluation.study", "run_study"),
        ("energy_margin.evaluation.budget", "copy_dataset"),
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
        # The verbs of every stage a user calls, and their typed results.
        "calibrate",
        "learn",
        "design_search",
        "design_sweep",
        "score_state",
        "LiveModelScorer",
        "resolve_task",
        "Evaluation",
        "SweepResult",
        "DesignSearchResult",
        "LearnResult",
        "LiveScore",
    ):
        assert callable(getattr(energy_margin, name)), name
    assert callable(register_task)
    assert energy_margin.generate is energy_margin.generate_dataset
    assert energy_margin.learn is energy_margin.learn_pipeline
    assert sorted(energy_margin.__all__) == energy_margin.__all__
    for name in energy_margin.__all__:
        assert getattr(energy_margin, name) is not None, name


#: Built-in task names that code outside ``tasks/`` may still spell out, as (module path under the
#: package, top-level name that holds the spelling), each with its reason. Everything else asks the
#: task through its hooks (:class:`~energy_margin.tasks.base.Task`), so a task registered from
#: another package gets the same behaviour.
TASK_NAME_ALLOWED = {
    # The paper's published Table I, keyed by the paper's two tasks: data, not a branch (reproduce
    # runs the paper's tasks by iterating it).
    ("report/paper.py", "PAPER_TABLE_I"),
    # The command-space registry's built-in entries; register_command_space adds other tasks'.
    ("control/commands.py", "_COMMAND_SPACES"),
}


def builtin_task_names() -> set[str]:
    """The names of the tasks the package registers itself."""
    from energy_margin.tasks import PushingTask, SceneTask, ScoopingTask

    return {PushingTask.name, ScoopingTask.name, SceneTask.name}


def task_name_uses(tree: ast.Module, names: set[str]) -> list[tuple[int, str, str]]:
    """(line, top-level name, what) of every branch on a task name in a module.

    Found: comparisons with a name (``==``, ``!=``, ``in``, ``is``, also against a literal tuple,
    list or set of names), dictionary keys, set members, subscripts (``table["pushing"]``),
    ``case`` patterns, and loops over a literal collection of names.
    """

    def spelled(node: ast.AST | None) -> list[str]:
        if isinstance(node, ast.Constant) and node.value in names:
            return [str(node.value)]
        if isinstance(node, ast.Tuple | ast.List | ast.Set):
            return [str(e.value) for e in node.elts if isinstance(e, ast.Constant) and e.value in names]
        return []

    found: list[tuple[int, str, str]] = []
    for statement in tree.body:
        if isinstance(statement, ast.FunctionDef | ast.AsyncFunctionDef | ast.ClassDef):
            scope = statement.name
        elif isinstance(statement, ast.Assign) and isinstance(statement.targets[0], ast.Name):
            scope = statement.targets[0].id
        elif isinstance(statement, ast.AnnAssign) and isinstance(statement.target, ast.Name):
            scope = statement.target.id
        else:
            scope = "<module>"
        for node in ast.walk(statement):
            hits: list[tuple[str, list[str]]] = []
            if isinstance(node, ast.Compare):
                hits = [("comparison", spelled(operand)) for operand in (node.left, *node.comparators)]
            elif isinstance(node, ast.Dict):
                hits = [("dictionary key", spelled(key)) for key in node.keys if isinstance(key, ast.Constant)]
            elif isinstance(node, ast.Set):
                hits = [("set member", spelled(node))]
            elif isinstance(node, ast.Subscript):
                hits = [("subscript", spelled(node.slice))]
            elif isinstance(node, ast.MatchValue):
                hits = [("case pattern", spelled(node.value))]
            elif isinstance(node, ast.For | ast.AsyncFor | ast.comprehension):
                hits = [("loop", spelled(node.iter))]
            for what, spellings in hits:
                found.extend((getattr(node, "lineno", statement.lineno), scope, f"{what} {s!r}") for s in spellings)
    return sorted(found)


def task_name_branches() -> list[str]:
    """``path:line (scope): what`` of every branch on a built-in task name outside ``tasks/``."""
    names = builtin_task_names()
    branches = []
    for path in sorted(PACKAGE.rglob("*.py")):
        relative = path.relative_to(PACKAGE).as_posix()
        if relative.startswith("tasks/"):
            continue
        for line, scope, what in task_name_uses(ast.parse(path.read_text(encoding="utf-8")), names):
            branches.append((relative, scope, f"{relative}:{line} ({scope}): {what}"))
    return [text for relative, scope, text in branches if (relative, scope) not in TASK_NAME_ALLOWED] + [
        f"allowed but unused: {entry}"
        for entry in sorted(TASK_NAME_ALLOWED - {(relative, scope) for relative, scope, _ in branches})
    ]


def test_no_code_outside_the_tasks_branches_on_a_built_in_task_name() -> None:
    assert task_name_branches() == []


def test_the_task_name_scan_finds_every_kind_of_branch() -> None:
    source = (
        "def f(task, d):\n"
        "    a = task == 'pushing'\n"
        "    b = task.name in ('scooping', 'other')\n"
        "    c = {'pushing': 1, 'x': 2}\n"
        "    e = {'scooping'}\n"
        "    g = d['scene']\n"
        "    for t in ('pushing', 'scooping'):\n"
        "        pass\n"
        "    match task:\n"
        "        case 'scene':\n"
        "            pass\n"
        "    return d.get('x') == 'other', f'{task}-pushing', 'pushing'.upper()\n"
        "TABLE = {'pushing': 1}\n"
    )
    uses = task_name_uses(ast.parse(source), builtin_task_names())
    assert [(line, what) for line, _, what in uses] == [
        (2, "comparison 'pushing'"),
        (3, "comparison 'scooping'"),
        (4, "dictionary key 'pushing'"),
        (5, "set member 'scooping'"),
        (6, "subscript 'scene'"),
        (7, "loop 'pushing'"),
        (7, "loop 'scooping'"),
        (10, "case pattern 'scene'"),
        (13, "dictionary key 'pushing'"),
    ]
    assert {scope for _, scope, _ in uses} == {"f", "TABLE"}


if __name__ == "__main__":
    graph = import_graph()
    print(f"{len(graph)} modules, {sum(len(t) for t in graph.values())} imports")
    print("cycles:", cycles(graph) or "none")
    print("order breaks:", order_breaks(graph) or "none")


def _module_level_names(tree: ast.Module) -> set[str]:
    """Names a module binds at its top level (definitions, assignments, imports, TYPE_CHECKING imports)."""
    names: set[str] = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.FunctionDef | ast.AsyncFunctionDef | ast.ClassDef) and node in tree.body:
            names.add(node.name)
        elif isinstance(node, ast.Import | ast.ImportFrom):
            names |= {(alias.asname or alias.name).split(".")[0] for alias in node.names}
        elif isinstance(node, ast.Assign | ast.AnnAssign) and node in tree.body:
            for target in node.targets if isinstance(node, ast.Assign) else [node.target]:
                if isinstance(target, ast.Name):
                    names.add(target.id)
    return names


def test_every_module_declares_its_public_names() -> None:
    """``__all__`` in every module, each name in it bound there (read with ``ast``), a lazy package's importable."""
    missing, unbound = [], []
    for name, path in sorted(module_names().items()):
        tree = ast.parse(path.read_text(encoding="utf-8"))
        declared = [
            node.value
            for node in tree.body
            if isinstance(node, ast.Assign | ast.AnnAssign)
            and any(
                isinstance(target, ast.Name) and target.id == "__all__"
                for target in (node.targets if isinstance(node, ast.Assign) else [node.target])
            )
        ]
        if not declared:
            missing.append(name)
            continue
        bound = _module_level_names(tree)
        if not isinstance(declared[0], ast.List | ast.Tuple) or "__getattr__" in bound:
            continue  # a lazy package's names load on first use: imported below
        names = [e.value for e in declared[0].elts if isinstance(e, ast.Constant)]
        unbound += [f"{name}.{public}" for public in names if public not in bound]
    assert not missing, f"modules without __all__: {missing}"
    assert not unbound, f"names in __all__ that the module does not bind: {unbound}"
    import importlib

    # energy_margin.integrations loads simulator stacks (dm_control, Gymnasium): its own tests import them.
    for package in ("energy_margin", "energy_margin.design", "energy_margin.experiments"):
        module = importlib.import_module(package)
        for public in module.__all__:
            assert getattr(module, public) is not None, f"{package}.{public}"

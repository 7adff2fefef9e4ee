"""How the code reads to a maintainer: sizes per stage, the longest modules and functions, contract breaks.

Reads a checkout of the project (this one by default, or ``--root`` another, e.g. a worktree of an
earlier commit) and prints one table; ``--out`` writes the figures as JSON.

* files and lines per stage (``src/energy_margin/<stage>``);
* the largest module and function, and how many modules exceed 450 lines and functions 80;
* ``raise ValueError`` statements in ``src`` (the errors contract wants ``InvalidParameterError``
  or another ``EnergyMarginError``);
* library string literals (outside ``cli/``, docstrings left out) that name a ``--flag``;
* modules that declare ``__all__``;
* the command line: commands and options (from the parsers of that checkout);
* README lines, words and numbers;
* pairs of repeated code in ``src`` (the ``duplicates`` command, when it is on the PATH).

    python benchmarks/codebase_measures.py --out docs/figures/codebase_after.json
    python benchmarks/codebase_measures.py --root /tmp/before --out docs/figures/codebase_before.json
"""

from __future__ import annotations

import ast
import json
import re
import shutil
import subprocess
from pathlib import Path
from typing import Any

from checkout import checkout_arguments, commit_of, run_on

MODULE_LIMIT = 450
FUNCTION_LIMIT = 80
FLAG = re.compile(r"(?<![\w-])--[a-z][a-z0-9-]+")
NUMBER = re.compile(r"(?<![\w.])\d+(?:[.,]\d+)*(?![\w])")

#: Run in the measured checkout's interpreter path: the command line's commands and options.
_CLI_COUNT = """
import argparse, json
from energy_margin.cli.app import build_parser
parser = build_parser()
commands = options = 0
for action in parser._actions:
    if isinstance(action, argparse._SubParsersAction):
        for sub in action.choices.values():
            commands += 1
            options += sum(1 for a in sub._actions if a.option_strings and a.dest != "help")
print(json.dumps({"commands": commands, "options": options}))
"""


def _docstring(node: ast.AST) -> ast.Expr | None:
    """The docstring statement of a module, class or function, or ``None``."""
    if isinstance(node, ast.Module | ast.ClassDef | ast.FunctionDef | ast.AsyncFunctionDef) and node.body:
        first = node.body[0]
        if isinstance(first, ast.Expr) and isinstance(first.value, ast.Constant) and isinstance(first.value.value, str):
            return first
    return None


def _docstring_nodes(tree: ast.AST) -> set[int]:
    return {id(statement.value) for node in ast.walk(tree) if (statement := _docstring(node)) is not None}


def _code_lines(node: ast.FunctionDef | ast.AsyncFunctionDef) -> int:
    """A function's lines without its docstring."""
    total = int(node.end_lineno or node.lineno) - node.lineno + 1
    statement = _docstring(node)
    if statement is not None:
        total -= int(statement.end_lineno or statement.lineno) - statement.lineno + 1
    return total


def _assigned(tree: ast.Module) -> list[ast.expr]:
    """The targets of the module-level assignments of ``tree``."""
    targets: list[ast.expr] = []
    for node in tree.body:
        if isinstance(node, ast.Assign):
            targets += node.targets
        elif isinstance(node, ast.AnnAssign):
            targets.append(node.target)
    return targets


def source_measures(package: Path) -> dict[str, Any]:
    """Sizes, long modules and functions, ``ValueError`` raises, flag names and ``__all__`` of ``package``."""
    stages: dict[str, dict[str, int]] = {}
    modules: list[tuple[int, str]] = []
    functions: list[tuple[int, str]] = []
    code: list[tuple[int, str]] = []
    value_errors = flag_literals = with_all = 0
    for path in sorted(package.rglob("*.py")):
        relative = path.relative_to(package).as_posix()
        text = path.read_text(encoding="utf-8")
        lines = len(text.splitlines())
        stage = relative.split("/")[0] if "/" in relative else "(foundations)"
        entry = stages.setdefault(stage, {"files": 0, "lines": 0})
        entry["files"] += 1
        entry["lines"] += lines
        modules.append((lines, relative))
        tree = ast.parse(text)
        docstrings = _docstring_nodes(tree)
        for node in ast.walk(tree):
            if isinstance(node, ast.FunctionDef | ast.AsyncFunctionDef):
                name = f"{relative}:{node.name}"
                functions.append((int(node.end_lineno or node.lineno) - node.lineno + 1, name))
                code.append((_code_lines(node), name))
            elif isinstance(node, ast.Raise) and node.exc is not None:
                call = node.exc.func if isinstance(node.exc, ast.Call) else node.exc
                if isinstance(call, ast.Name) and call.id == "ValueError":
                    value_errors += 1
            elif (
                isinstance(node, ast.Constant)
                and isinstance(node.value, str)
                and id(node) not in docstrings
                and not relative.startswith("cli/")
                and FLAG.search(node.value)
            ):
                flag_literals += 1
        if any(isinstance(target, ast.Name) and target.id == "__all__" for target in _assigned(tree)):
            with_all += 1
    modules.sort(reverse=True)
    functions.sort(reverse=True)
    return {
        "stages": dict(sorted(stages.items())),
        "modules": len(modules),
        "lines": sum(lines for lines, _ in modules),
        "largest_module": {"path": modules[0][1], "lines": modules[0][0]},
        "largest_function": {"name": functions[0][1], "lines": functions[0][0]},
        "modules_over_limit": [{"path": p, "lines": n} for n, p in modules if n > MODULE_LIMIT],
        "functions_over_limit": [{"name": f, "lines": n} for n, f in functions if n > FUNCTION_LIMIT],
        "functions_over_limit_without_docstring": [
            {"name": f, "lines": n} for n, f in sorted(code, reverse=True) if n > FUNCTION_LIMIT
        ],
        "value_error_raises": value_errors,
        "library_flag_literals": flag_literals,
        "modules_with_all": with_all,
    }


def readme_measures(readme: Path) -> dict[str, int]:
    """Lines, words and numbers of the README (code blocks included, as a reader sees them)."""
    text = readme.read_text(encoding="utf-8")
    return {"lines": len(text.splitlines()), "words": len(text.split()), "numbers": len(NUMBER.findall(text))}


def cli_measures(root: Path) -> dict[str, int] | None:
    """Commands and options of the checkout's command line; ``None`` when its parser cannot be built here."""
    return run_on(root, _CLI_COUNT)


def _is_listing(line: str) -> bool:
    """A line of an ``__all__`` list: a quoted name, the list's opening or its end."""
    return bool(re.match(r'\s*"\w+",\s*$', line)) or "__all__" in line or line.strip() in ("]", "")


def duplicate_pairs(package: Path) -> dict[str, int] | None:
    """Pairs of places in ``package`` sharing six or more lines (``duplicates``), and how many of them
    have an ``__all__`` list on one side (a re-export list repeats the names its module imports);
    ``None`` without the command.
    """
    if shutil.which("duplicates") is None:
        return None
    found = subprocess.run(
        ["duplicates", "--repo", str(package), "--most", "200", "--seconds", "120"],
        capture_output=True,
        text=True,
        check=False,
    )
    first = found.stdout.splitlines()[0] if found.stdout else ""
    if first.startswith("no duplicates"):
        return {"pairs": 0, "with_an_all_list": 0}
    match = re.match(r"(\d+) pairs?", first)
    if match is None:
        return None
    listing = 0
    for row in found.stdout.splitlines():
        for path, start, end in re.findall(r"(\S+\.py):(\d+)-(\d+)", row if re.match(r"D\d+ ", row) else ""):
            lines = (package / path).read_text(encoding="utf-8").splitlines()[int(start) - 1 : int(end)]
            if all(
                re.match(r'\s*"\w+",\s*$', line) or "__all__" in line or line.strip() in ("]", "") for line in lines
            ):
                listing += 1
                break
    return {"pairs": int(match.group(1)), "with_an_all_list": listing}


def main() -> None:
    args = checkout_arguments(__doc__)
    root = args.root
    package = root / "src" / "energy_margin"
    commit = commit_of(root)
    figures: dict[str, Any] = {"commit": commit, **source_measures(package)}
    figures["readme"] = readme_measures(root / "README.md")
    figures["cli"] = cli_measures(root)
    figures["duplicate_pairs"] = duplicate_pairs(package)
    figures["counts"] = {
        "modules_over_limit": len(figures["modules_over_limit"]),
        "functions_over_limit": len(figures["functions_over_limit"]),
        "functions_over_limit_without_docstring": len(figures["functions_over_limit_without_docstring"]),
    }
    width = max(len(stage) for stage in figures["stages"])
    print(f"checkout {root} at {commit}")
    for stage, entry in figures["stages"].items():
        print(f"  {stage:<{width}}  {entry['files']:>3} files  {entry['lines']:>6} lines")
    print(f"  {'total':<{width}}  {figures['modules']:>3} files  {figures['lines']:>6} lines")
    print(f"largest module    {figures['largest_module']['path']} ({figures['largest_module']['lines']} lines)")
    print(f"largest function  {figures['largest_function']['name']} ({figures['largest_function']['lines']} lines)")
    print(f"modules over {MODULE_LIMIT} lines: {len(figures['modules_over_limit'])}")
    print(
        f"functions over {FUNCTION_LIMIT} lines: {len(figures['functions_over_limit'])} "
        f"({len(figures['functions_over_limit_without_docstring'])} without their docstrings)"
    )
    print(f"raise ValueError: {figures['value_error_raises']}")
    print(f"library strings naming a --flag: {figures['library_flag_literals']}")
    print(f"modules declaring __all__: {figures['modules_with_all']} of {figures['modules']}")
    if figures["cli"]:
        print(f"command line: {figures['cli']['commands']} commands, {figures['cli']['options']} options")
    readme = figures["readme"]
    print(f"README: {readme['lines']} lines, {readme['words']} words, {readme['numbers']} numbers")
    pairs = figures["duplicate_pairs"]
    if pairs is not None:
        listing = pairs["with_an_all_list"]
        print(f"repeated-code pairs in src: {pairs['pairs']} ({listing} with an __all__ list on one side)")
    if args.out:
        args.out.write_text(json.dumps(figures, indent=2) + "\n", encoding="utf-8")


if __name__ == "__main__":
    main()

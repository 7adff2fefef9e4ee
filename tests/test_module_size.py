"""No module of the package is longer than 450 lines, except the few listed that are still longer.

The list holds each such module with its length when it was written down: a module on it may
shrink (then lower its number, or drop it below 450 lines) but not grow, and no other module may
pass 450 lines. ``python tests/test_module_size.py`` prints the modules over the limit and the
functions longer than 80 lines.
"""

from __future__ import annotations

import ast
from pathlib import Path

import energy_margin

PACKAGE = Path(energy_margin.__file__).parent
MAX_LINES = 450
MAX_FUNCTION_LINES = 80

#: Modules still over :data:`MAX_LINES`, by path inside the package, with their line counts.
ALLOWED: dict[str, int] = {}


def module_lines() -> dict[str, int]:
    """Lines of every module of the package, by path inside it."""
    return {
        path.relative_to(PACKAGE).as_posix(): len(path.read_text(encoding="utf-8").splitlines())
        for path in sorted(PACKAGE.rglob("*.py"))
    }


def long_functions() -> list[tuple[int, str]]:
    """Functions and methods longer than :data:`MAX_FUNCTION_LINES` (lines, ``module:name``), longest first."""
    found = []
    for path in sorted(PACKAGE.rglob("*.py")):
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            if isinstance(node, ast.FunctionDef | ast.AsyncFunctionDef):
                length = (node.end_lineno or node.lineno) - node.lineno + 1
                if length > MAX_FUNCTION_LINES:
                    found.append((length, f"{path.relative_to(PACKAGE).as_posix()}:{node.name}"))
    return sorted(found, reverse=True)


def test_no_module_is_longer_than_the_limit() -> None:
    over = {name: lines for name, lines in module_lines().items() if lines > ALLOWED.get(name, MAX_LINES)}
    assert not over, f"modules over {MAX_LINES} lines (or longer than their allowance): {over}"


def test_the_allowances_name_modules_still_over_the_limit() -> None:
    lines = module_lines()
    stale = {name: lines.get(name) for name in ALLOWED if lines.get(name, 0) <= MAX_LINES}
    assert not stale, f"no longer over {MAX_LINES} lines (drop from ALLOWED): {stale}"


if __name__ == "__main__":
    for name, lines in sorted(module_lines().items(), key=lambda item: -item[1]):
        if lines > MAX_LINES:
            print(f"{lines:5d}  {name}")
    print()
    for length, name in long_functions():
        print(f"{length:5d}  {name}")

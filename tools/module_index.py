"""Every module of the package with the first line of its docstring, as Markdown.

``python tools/module_index.py`` prints the table; the docs site's hook (``tools/mkdocs_hooks.py``)
puts it in ``docs/reference/architecture.md`` at every build, so the page lists every module there
is, read from the source without importing it.
"""

from __future__ import annotations

import ast
from pathlib import Path

PACKAGE = Path(__file__).resolve().parents[1] / "src" / "energy_margin"
#: Where the generated table goes in a page.
MARKER = "<!-- module-index -->"


def first_line(path: Path) -> str:
    """The first line of a module's docstring ('' without one)."""
    docstring = ast.get_docstring(ast.parse(path.read_text(encoding="utf-8")))
    return docstring.strip().splitlines()[0] if docstring else ""


def modules(package: Path = PACKAGE) -> list[tuple[str, str]]:
    """``(dotted name, first docstring line)`` of every module, packages first, in source order."""
    found = []
    for path in sorted(package.rglob("*.py")):
        parts = path.relative_to(package.parent).with_suffix("").parts
        if parts[-1] == "__init__":
            parts = parts[:-1]
        found.append((".".join(parts), first_line(path)))
    return sorted(found)


def markdown(package: Path = PACKAGE) -> str:
    """The module table."""
    lines = ["| module | what it holds |", "|---|---|"]
    for name, line in modules(package):
        cell = line.replace("|", "\\|")
        lines.append(f"| `{name}` | {cell} |")
    return "\n".join(lines) + "\n"


if __name__ == "__main__":
    print(markdown(), end="")

"""Figures in the README and docs: how many come from a results file, how many are copied by hand.

Reads a checkout (this one by default, or ``--root`` another) and counts, per page, the decimal
numbers (``0.895``, ``1.20``) a reader sees: inside a ``<!-- fig ... -->`` marker or a generated
``<!-- table ... -->`` block (inserted from a results file by ``tools/figures.py``), or written by
hand. Code blocks are left out (commands and their settings, not figures).

    python benchmarks/docs_figures.py --out docs/figures/docs_figures_after.json
    python benchmarks/docs_figures.py --root /tmp/before --out docs/figures/docs_figures_before.json
"""

from __future__ import annotations

import re
import sys
from pathlib import Path
from typing import Any

from checkout import ROOT, checkout_arguments, commit_of, write_figures

sys.path.insert(0, str(ROOT / "tools"))
from figures import MARKER, TABLE

DECIMAL = re.compile(r"(?<![\w.])\d+\.\d+(?![\w.])")
FENCE = re.compile(r"```.*?```", re.S)
PAGES = ("README.md", "docs/**/*.md")
#: Results files themselves (written by the commands that measured them), not pages that quote them.
RESULTS = "docs/figures/"


def page_counts(text: str) -> dict[str, int]:
    """Decimals of one page: from results files (markers, tables) and by hand."""
    text = FENCE.sub("", text)
    # What a reader sees of a marker or a table block: its value or its rows, not its source.
    shown = [match.group("value") for match in MARKER.finditer(text)]
    shown += [match.group("rows") for match in TABLE.finditer(text)]
    quoted = sum(len(DECIMAL.findall(part)) for part in shown)
    by_hand = len(DECIMAL.findall(TABLE.sub("", MARKER.sub("", text))))
    return {"from_files": quoted, "by_hand": by_hand}


def measure(root: Path) -> dict[str, Any]:
    """Counts per page and in all, for the checkout ``root``."""
    found: set[Path] = set()
    for pattern in PAGES:
        found.update(root.glob(pattern))
    pages = {
        str(path.relative_to(root)): page_counts(path.read_text(encoding="utf-8"))
        for path in sorted(found)
        if ".venv" not in path.parts and not str(path.relative_to(root)).startswith(RESULTS)
    }
    return {
        "pages": pages,
        "from_files": sum(entry["from_files"] for entry in pages.values()),
        "by_hand": sum(entry["by_hand"] for entry in pages.values()),
        "readme_by_hand": pages.get("README.md", {}).get("by_hand", 0),
    }


def main() -> None:
    args = checkout_arguments(__doc__)
    root = args.root
    commit = commit_of(root)
    figures = {"commit": commit, **measure(root)}
    print(f"checkout {root} at {commit}")
    for page, entry in sorted(figures["pages"].items(), key=lambda item: -item[1]["by_hand"]):
        if entry["by_hand"] or entry["from_files"]:
            print(f"  {page:<40} {entry['from_files']:>5} from files {entry['by_hand']:>5} by hand")
    print(f"  {'all pages':<40} {figures['from_files']:>5} from files {figures['by_hand']:>5} by hand")
    write_figures(args.out, figures)


if __name__ == "__main__":
    main()

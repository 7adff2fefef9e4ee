"""The paper's reported values, as the report prints them, written as a file the pages quote.

``energy_margin.report.paper`` holds the paper's Table I and Fig. 2 values, which ``reproduce``'s
report prints beside the reproduced ones. This writes them as JSON (a value with its spread as
``{"mean": m, "std": s}``), so the pages quote the same numbers through ``tools/figures.py``
instead of copying them by hand.

    python benchmarks/paper_values.py --out docs/figures/paper.json
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path
from typing import Any

from energy_margin.report.paper import PAPER_FIG_2, PAPER_TABLE_I

__all__ = ["as_json"]


def _value(value: Any) -> Any:
    if isinstance(value, tuple):
        mean, std = value
        return {"mean": mean, "std": std}
    return value


def as_json() -> dict[str, Any]:
    """Table I per task and Fig. 2 per number of objects (keys as strings), spreads as mean and std."""
    return {
        "source": "energy_margin.report.paper (the paper's Table I and Fig. 2)",
        "table_1": {task: {key: _value(value) for key, value in row.items()} for task, row in PAPER_TABLE_I.items()},
        "fig_2": {str(n): {key: _value(value) for key, value in row.items()} for n, row in PAPER_FIG_2.items()},
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n", 1)[0])
    parser.add_argument("--out", type=Path, required=True, help="the JSON file to write")
    args = parser.parse_args()
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(json.dumps(as_json(), indent=2) + "\n", encoding="utf-8")


if __name__ == "__main__":
    main()

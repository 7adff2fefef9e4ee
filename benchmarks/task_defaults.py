"""The built-in tasks' default settings and the reference import's constants, as the code holds them.

The method reference (docs/reference/method.md) and the reference page (docs/results/reference.md)
quote the tasks' geometry, scripts and regions; they quote them from this file, which reads the
code's own defaults (``PushingConfig()``, ``ScoopingConfig()``) and the constants of
``energy_margin.data.reference_convert``, so a changed default shows as a disagreement in
``tools/figures.py`` instead of a stale page. Nothing is measured.

    python benchmarks/task_defaults.py --out docs/figures/task_defaults.json
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

from checkout import checkout_arguments, commit_of, run_on, write_figures

_DUMP = """
import dataclasses, json
from energy_margin.data import reference_convert
from energy_margin.tasks.pushing_config import PushingConfig
from energy_margin.tasks.scooping_config import ScoopingConfig

def plain(config):
    return {field.name: getattr(config, field.name) for field in dataclasses.fields(config)}

constants = {
    name: value
    for name, value in vars(reference_convert).items()
    if name.isupper() and isinstance(value, (int, float)) and not isinstance(value, bool)
}
print(json.dumps({
    "pushing": plain(PushingConfig()),
    "scooping": plain(ScoopingConfig()),
    "reference_import": constants,
}))
"""


def defaults(root: Path) -> dict[str, Any]:
    """The tasks' defaults and the import's constants of the checkout ``root``."""
    found = run_on(root, _DUMP, required=True)
    assert isinstance(found, dict)
    return dict(found)


def main() -> None:
    args = checkout_arguments(__doc__)
    figures = {"commit": commit_of(args.root), **defaults(args.root)}
    for task in ("pushing", "scooping"):
        print(f"{task}: {len(figures[task])} settings")
    print(f"reference import: {len(figures['reference_import'])} constants")
    write_figures(args.out, figures)


if __name__ == "__main__":
    main()

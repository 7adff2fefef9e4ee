"""Write a copy of a scene file without its ``[perturbation]`` table, so every perturbation setting is derived.

The copy's file paths (``mjcf``, ``motion.ctrl_file``) are made absolute so it can live anywhere.

    python benchmarks/scene_without_perturbation.py examples/jaco/jaco.toml runs/jaco-derived.toml
"""

from __future__ import annotations

import re
import sys
from pathlib import Path


def without_perturbation(text: str, folder: Path) -> str:
    """The scene file ``text`` (from ``folder``) without its ``[perturbation]`` table, paths absolute."""
    text = re.sub(r"^\[perturbation\]\n(?:(?!\[).*\n)*", "", text, flags=re.MULTILINE)

    def absolute(match: re.Match[str]) -> str:
        return f'{match.group(1)} = "{(folder / match.group(2)).resolve()}"'

    return re.sub(r'^(mjcf|\s*ctrl_file)\s*=\s*"([^"]+)"', absolute, text, flags=re.MULTILINE)


def main(argv: list[str]) -> int:
    if len(argv) != 2:
        print(__doc__.strip().splitlines()[-1].strip(), file=sys.stderr)
        return 2
    source, target = Path(argv[0]).resolve(), Path(argv[1])
    target.parent.mkdir(parents=True, exist_ok=True)
    target.write_text(without_perturbation(source.read_text(), source.parent))
    return 0


if __name__ == "__main__":
    raise SystemExit(main(sys.argv[1:]))

"""Write a copy of a scene file without its ``[perturbation]`` values: the fixed defaults, or derived ones.

With ``--derive`` the copy's table is ``[perturbation] derive = true`` (every setting derived from the
scene, tasks/scene_defaults.py); without it the table is left out (the fixed defaults). The copy's
file paths (``mjcf``, ``motion.ctrl_file``) are made absolute so it can live anywhere.

    python benchmarks/scene_without_perturbation.py examples/jaco/jaco.toml runs/jaco-derived.toml --derive
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
    derive = "--derive" in argv
    paths = [arg for arg in argv if arg != "--derive"]
    if len(paths) != 2:
        print(__doc__.strip().splitlines()[-1].strip(), file=sys.stderr)
        return 2
    source, target = Path(paths[0]).resolve(), Path(paths[1])
    target.parent.mkdir(parents=True, exist_ok=True)
    text = without_perturbation(source.read_text(), source.parent)
    target.write_text(text + ("\n[perturbation]\nderive = true\n" if derive else ""))
    return 0


if __name__ == "__main__":
    raise SystemExit(main(sys.argv[1:]))

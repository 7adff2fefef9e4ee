"""``energy-margin scene``: print what a scene file declares and draw it at t = 0 with its sets."""

from __future__ import annotations

import argparse
import os
from pathlib import Path

from energy_margin.cli.common import add_seed, require_matplotlib

NAME = "scene"
SUMMARY = "print what a scene file declares and write a picture of it at t = 0 with the capture and success sets"
EXAMPLES = ("energy-margin scene my_scene.toml --picture my_scene.png",)


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Arguments of ``scene``."""
    parser.add_argument("scene", metavar="SCENE.toml", help="the scene file (docs/scenes.md)")
    parser.add_argument("--picture", help="PNG to write (default: SCENE.png beside the scene file)")
    parser.add_argument("--no-picture", action="store_true", help="only print the summary")
    add_seed(parser)


def run(args: argparse.Namespace) -> int:
    """Print the summary, then render the picture with MuJoCo's renderer."""
    from energy_margin.tasks import get_task
    from energy_margin.tasks.scene_task import SceneTask

    task = get_task("scene", {"scene_file": os.path.abspath(args.scene)})
    assert isinstance(task, SceneTask)
    from energy_margin.report.scene_view import describe_scene, render_scene

    for line in describe_scene(task):
        print(line)
    if args.no_picture:
        return 0
    require_matplotlib()
    picture = Path(args.picture) if args.picture else Path(args.scene).with_suffix(".png")
    frame = render_scene(task, picture, seed=args.seed)
    captured = task.is_captured(frame)
    successful = task.is_successful(frame)
    print(
        f"start (seed {args.seed}): captured {'yes' if captured else 'no'}, successful {'yes' if successful else 'no'}"
    )
    print(f"wrote {picture}")
    return 0

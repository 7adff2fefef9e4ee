"""``energy-margin scene``: print what a scene file declares and draw it at t = 0 with its sets."""

from __future__ import annotations

import argparse
import json
import os
from pathlib import Path
from typing import Any

from energy_margin.cli.common import DeprecatedAlias, add_seed, require_matplotlib

__all__ = [
    "EXAMPLES",
    "NAME",
    "SUMMARY",
    "add_arguments",
    "run",
]

NAME = "scene"
SUMMARY = "print what a scene file declares and write a picture of it at t = 0 with the capture and success sets"
EXAMPLES = (
    "energy-margin scene my_scene.toml --picture my_scene.png",
    "energy-margin scene --from-gym Pusher-v5 --object-bodies object --out pusher.toml",
)


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Arguments of ``scene``."""
    parser.add_argument("scene", nargs="?", metavar="SCENE.toml", help="the scene file (docs/howto/scenes.md)")
    parser.add_argument(
        "--from-gym",
        metavar="[MODULE:]ENV_ID",
        help="write a starter scene file for this Gymnasium MuJoCo environment (needs --object-bodies and --out); "
        "MODULE is imported first (the package that registers the id, e.g. metaworld:Meta-World/MT1)",
    )
    parser.add_argument(
        "--env-kwargs",
        metavar="JSON",
        help="with --from-gym: keyword arguments of gymnasium.make, a JSON object "
        '(e.g. \'{"env_name": "bin-picking-v3"}\')',
    )
    parser.add_argument(
        "--object-bodies",
        "--objects",
        dest="objects",
        action=DeprecatedAlias,
        old="--objects",
        help="with --from-gym: object body names or glob patterns, comma separated (--objects is its old name)",
    )
    parser.add_argument(
        "--out",
        metavar="SCENE.toml",
        help="with --from-gym: the scene file to write; the environment's model goes beside it, as SCENE.xml "
        "(a copy of its model file when that compiles to the same model) or SCENE.mjb (the compiled model)",
    )
    parser.add_argument("--capture-radius", type=float, help="with --from-gym: radius of the starter capture region, m")
    parser.add_argument("--picture", help="PNG to write (default: SCENE.png beside the scene file)")
    parser.add_argument("--no-picture", action="store_true", help="only print the summary")
    parser.add_argument(
        "--camera",
        metavar="AZIMUTH,ELEVATION[,DISTANCE]",
        help="the picture's camera, degrees and m (default: heading 135, pitch -60, at the distance that frames "
        "the objects and the regions)",
    )
    add_seed(parser)


def run(args: argparse.Namespace) -> int:
    """Print the summary, then render the picture with MuJoCo's renderer."""
    from energy_margin.errors import EnergyMarginError
    from energy_margin.tasks import get_task
    from energy_margin.tasks.scene_task import SceneTask

    if args.from_gym is not None:
        args.scene = _from_gym(args)
    elif args.env_kwargs is not None:
        raise EnergyMarginError("--env-kwargs applies to --from-gym only")
    elif args.scene is None:
        raise EnergyMarginError("give a scene file, or --from-gym ENV_ID --object-bodies PATTERN --out SCENE.toml")
    camera = None
    if args.camera is not None:
        from energy_margin.report.scene_view import parse_camera

        camera = parse_camera(args.camera)
    task = get_task("scene", {"scene_file": os.path.abspath(args.scene)})
    assert isinstance(task, SceneTask)
    from energy_margin.report.scene_view import describe_scene, render_scene

    for line in describe_scene(task):
        print(line)
    if args.no_picture:
        return 0
    require_matplotlib()
    picture = Path(args.picture) if args.picture else Path(args.scene).with_suffix(".png")
    frame = render_scene(task, picture, seed=args.seed, camera=camera)
    captured = task.is_captured(frame)
    successful = task.is_successful(frame)
    print(
        f"start (seed {args.seed}): captured {'yes' if captured else 'no'}, successful {'yes' if successful else 'no'}"
    )
    print(f"wrote {picture}")
    return 0


def _env_kwargs(text: str | None) -> dict[str, Any]:
    """The JSON object of ``--env-kwargs`` (empty without one)."""
    from energy_margin.errors import EnergyMarginError

    if text is None:
        return {}
    try:
        value = json.loads(text)
    except json.JSONDecodeError as error:
        raise EnergyMarginError(f"--env-kwargs is not JSON ({error.msg} at character {error.pos}): {text}") from None
    if not isinstance(value, dict):
        raise EnergyMarginError(f"--env-kwargs must be a JSON object of keyword arguments, got {text}")
    return value


def _from_gym(args: argparse.Namespace) -> str:
    """Write the starter scene of ``--from-gym`` and print what was guessed; returns its path."""
    from energy_margin.errors import EnergyMarginError

    if args.scene is not None:
        raise EnergyMarginError("give either a scene file or --from-gym, not both")
    if not args.objects or not args.out:
        raise EnergyMarginError("--from-gym needs --object-bodies PATTERN and --out SCENE.toml")
    if args.capture_radius is not None and not args.capture_radius > 0:
        raise EnergyMarginError(f"--capture-radius must be > 0, got {args.capture_radius}")
    env_kwargs = _env_kwargs(args.env_kwargs)
    try:
        import gymnasium  # noqa: F401
    except ImportError:
        raise EnergyMarginError("--from-gym needs Gymnasium: pip install 'energy-margin[gymnasium]'") from None
    from energy_margin.integrations.gym_scene import scene_from_environment
    from energy_margin.integrations.gymnasium import make_environment

    try:
        env = make_environment(args.from_gym, env_kwargs)
    except EnergyMarginError as error:
        raise EnergyMarginError(f"--from-gym {error}") from None
    try:
        written = scene_from_environment(
            env, objects=args.objects.split(","), out=args.out, capture_radius=args.capture_radius
        )
    finally:
        env.close()
    print(f"wrote {written.scene_file}")
    print(written.model_note)
    print(f"objects: {', '.join(written.objects)}")
    print(
        f"capture (a guess, edit it): within {written.capture_radius} m of "
        f"{written.end_effector[0]} {written.end_effector[1]!r}"
    )
    if written.goal is not None:
        print(f"success (a guess, edit it): near {written.goal[0]} {written.goal[1]!r}")
    else:
        print("success (a guess, edit it): objects stay up (no goal body or site found)")
    if not written.same_model:
        print(f"note: the saved model differs from the one {args.from_gym} compiled at run time")
    return str(written.scene_file)

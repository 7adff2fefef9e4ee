"""What the stack examples share (Fetch, Meta-World, robosuite, gym-aloha): pictures, timing, results, the CLI.

:class:`Canvas` draws an environment's ``MjModel`` / ``MjData`` with MuJoCo's own renderer
(``mjr_render``) on the GL context ``MUJOCO_GL`` names, EGL (headless) when it is unset: the
context is made here, so the choice holds even where MuJoCo was imported before the variable was
read. :func:`save_episodes` puts the pictured moments of a few episodes side by side, each with its
live scores. :func:`timing` sums up the live calls; :func:`cli` runs ``energy-margin``;
:func:`write_live_scores`, :func:`check_frames` and :func:`summary` put the live scores beside the
recorded dataset and read ``evaluate``'s result.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path
from typing import Any

import mujoco
import numpy as np

from energy_margin.data.dataset import load_dataset
from energy_margin.data.scores_file import SCORES_FILE, format_row, header


def _gl_context(width: int, height: int) -> Any:
    backend = os.environ.get("MUJOCO_GL", "").strip().lower() or "egl"
    if backend == "egl":
        from mujoco.egl import GLContext
    elif backend == "osmesa":
        from mujoco.osmesa import GLContext
    elif backend == "glfw":
        from mujoco.glfw import GLContext
    else:
        raise RuntimeError(f"MUJOCO_GL={backend!r}: not egl, osmesa or glfw")
    return GLContext(width, height)


class Canvas:
    """An offscreen picture of one model, from a free camera; ``close`` it when done.

    Args:
        model: the environment's model (only read: the render buffer is sized on a copy).
        width: pixels.
        height: pixels.
        lookat: the camera's target point (world, m).
        distance: from the target, m.
        azimuth: degrees.
        elevation: degrees.

    """

    def __init__(
        self,
        model: mujoco.MjModel,
        width: int,
        height: int,
        *,
        lookat: tuple[float, float, float],
        distance: float,
        azimuth: float,
        elevation: float,
    ) -> None:
        self.model = model
        self.width, self.height = width, height
        self._gl = _gl_context(width, height)
        self._gl.make_current()
        # The offscreen buffer must hold the picture; the environment's own model keeps its size.
        saved = int(model.vis.global_.offwidth), int(model.vis.global_.offheight)
        model.vis.global_.offwidth = max(saved[0], width)
        model.vis.global_.offheight = max(saved[1], height)
        try:
            self._context = mujoco.MjrContext(model, mujoco.mjtFontScale.mjFONTSCALE_150)
        finally:
            model.vis.global_.offwidth, model.vis.global_.offheight = saved
        mujoco.mjr_setBuffer(mujoco.mjtFramebuffer.mjFB_OFFSCREEN, self._context)
        self._scene = mujoco.MjvScene(model, maxgeom=10000)
        self._option = mujoco.MjvOption()
        self._camera = mujoco.MjvCamera()
        self._camera.type = mujoco.mjtCamera.mjCAMERA_FREE
        self._camera.lookat[:] = lookat
        self._camera.distance, self._camera.azimuth, self._camera.elevation = distance, azimuth, elevation
        self._viewport = mujoco.MjrRect(0, 0, width, height)

    def draw(self, data: mujoco.MjData) -> np.ndarray:
        """The picture of ``data``'s state, (height, width, 3) uint8."""
        self._gl.make_current()
        mujoco.mjv_updateScene(
            self.model, data, self._option, None, self._camera, mujoco.mjtCatBit.mjCAT_ALL, self._scene
        )
        mujoco.mjr_render(self._viewport, self._scene, self._context)
        pixels = np.empty((self.height, self.width, 3), dtype=np.uint8)
        mujoco.mjr_readPixels(pixels, None, self._viewport, self._context)
        return np.flipud(pixels).copy()

    def close(self) -> None:
        """Free the GL context."""
        self._context.free()
        self._gl.free()


def save_rows(path: Path, rows: list[list[tuple[np.ndarray, str]]]) -> None:
    """One row of captioned pictures per entry of ``rows`` (``(pixels, caption)``), as a PNG."""
    from PIL import Image, ImageDraw

    height, width = rows[0][0][0].shape[:2]
    picture = Image.new("RGB", (width * max(len(row) for row in rows), height * len(rows)), (255, 255, 255))
    for r, row in enumerate(rows):
        for c, (pixels, caption) in enumerate(row):
            tile = Image.fromarray(pixels)
            draw = ImageDraw.Draw(tile)
            draw.rectangle((0, 0, width, 12 * (caption.count("\n") + 1) + 6), fill=(255, 255, 255))
            draw.text((6, 3), caption, fill=(0, 0, 0))
            picture.paste(tile, (c * width, r * height))
    picture.save(path)


def save_episodes(path: Path, episodes: list[dict[str, Any]], step_s: float) -> None:
    """One row per episode (``frames``: step -> pixels), each moment captioned with its live scores."""
    rows = []
    for episode in episodes:
        row = []
        for step, pixels in sorted(episode["frames"].items()):
            caption = f"env seed {episode['env_seed']}, noise {episode['noise']:.2f}: "
            caption += f"{'success' if episode['success'] else 'failure'}\nstep {step} (t = {step * step_s:.2f} s)"
            if step in episode["steps"]:
                score = episode["scores"][episode["steps"].index(step)]
                caption += f": capture {score['capture_score']:.2f}, success {score['success_score']:.2f}"
            row.append((pixels, caption))
        rows.append(row)
    save_rows(path, rows)


def timing(episodes: list[dict[str, Any]]) -> dict[str, Any]:
    """Wall time per live call, ms, and tree expansions per call, over every episode's ``scores``."""
    calls = [score for episode in episodes for score in episode["scores"]]
    ms = np.array([score["ms"] for score in calls])
    expansions = np.array([score["expansions"] for score in calls])
    return {
        "calls": len(calls),
        "mean_ms": float(ms.mean()),
        "median_ms": float(np.median(ms)),
        "p95_ms": float(np.percentile(ms, 95)),
        "max_ms": float(ms.max()),
        "mean_expansions": float(expansions.mean()),
        "median_expansions": float(np.median(expansions)),
        "min_expansions": int(expansions.min()),
        "fraction_stopped_by_budget": float(np.mean([score["stopped_by"] == "budget" for score in calls])),
    }


def cli(*arguments: str, echo: bool = True) -> str:
    """Run ``energy-margin ARGUMENTS`` with this interpreter; its standard output (printed with ``echo``)."""
    done = subprocess.run(
        [sys.executable, "-m", "energy_margin", *arguments], check=True, capture_output=True, text=True
    )
    if echo:
        print(done.stdout, end="", flush=True)
    return done.stdout


def record_analyze_evaluate(
    scene: Path, files: list[str], frames: int, dataset: Path, iterations: int, seed: int
) -> tuple[str, dict[str, Any]]:
    """``energy-margin record``, ``analyze`` and ``evaluate`` of the recorded episodes; evaluate's text and JSON."""
    cli("record", "--scene", str(scene), *files, "--frames", str(frames), "--out", str(dataset), "--overwrite")
    cli(
        "analyze", str(dataset), "--expansions", str(iterations), "--workers", "1", "--seed", str(seed), "--no-progress"
    )
    printed = cli("evaluate", str(dataset))
    return printed, json.loads(cli("evaluate", str(dataset), "--json", echo=False))


def write_live_scores(directory: Path, episodes: list[dict[str, Any]]) -> None:
    """The live scores as ``scores.csv`` of a dataset (trajectory = episode, frame = scored state)."""
    lines = [header()]
    for trajectory, episode in enumerate(episodes):
        for frame, score in enumerate(episode["scores"]):
            row = {
                "trajectory": trajectory,
                "frame": frame,
                "capture_score": float(score["capture_score"]),
                "success_score": float(score["success_score"]),
                "nodes": int(score["nodes"]),
                "expansions": int(score["expansions"]),
                "runtime_s": float(score["ms"]) / 1000.0,
                "physics_s": 0.0,
                "seed": int(score["seed"]),
            }
            lines.append(format_row(row) + "\n")
    (directory / SCORES_FILE).write_text("".join(lines), encoding="utf-8")


def check_frames(directory: Path, files: list[Path], episodes: list[dict[str, Any]]) -> None:
    """Refuse a dataset whose frames are not the scored steps, or whose labels differ from the live ones."""
    dataset = load_dataset(directory)
    for trajectory, (path, episode) in enumerate(zip(files, episodes, strict=True)):
        with np.load(path) as rollout:
            expected = rollout["time"][episode["steps"]]
        found = dataset.arrays["frame_time"][trajectory]
        if found.shape != expected.shape or not np.allclose(found, expected, rtol=0.0, atol=1e-9):
            raise SystemExit(f"{path}: the dataset's frames {found} are not the scored steps {expected}")
        live = np.array(episode["labels"], dtype=bool)
        recorded = np.stack([dataset.arrays["captured"][trajectory], dataset.arrays["in_success"][trajectory]], 1)
        if not np.array_equal(live, recorded):
            raise SystemExit(f"{path}: the dataset's labels differ from the live ones")


def summary(result: dict[str, Any]) -> dict[str, Any]:
    """The AP of the energy margin and of the baselines, and the verdict, from ``evaluate``'s result."""
    keys = ("capture_ap", "capture_ap_window2", "success_ap", "success_ap_first_half")
    baselines = {
        name: {key: values.get(key) for key in keys if key in values}
        for name, values in result.get("baselines", {}).items()
    }
    return {
        **{key: result.get(key) for key in keys if key in result},
        "baselines": baselines,
        "verdict": result.get("verdict"),
    }

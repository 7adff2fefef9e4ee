"""Shared fixtures: tiny scenes and datasets built in code."""

from __future__ import annotations

import shutil
import signal
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest

from energy_margin.data.dataset import FRAMES_FILE
from energy_margin.data.generate import generate_dataset
from energy_margin.world.scene import Geom, RigidObject, Scene
from energy_margin.world.state import FrameState
from tiny_scene import TINY_MODEL, TINY_SCENE, write_tiny_scene

# Helper modules shared by test files: their asserts report the compared values too.
pytest.register_assert_rewrite("example_runs")

# A run started as a background job of a non-interactive shell (`cmd &`, `nohup`) inherits SIGINT
# ignored, and so would every command the tests start, which the Ctrl-C tests then cannot stop:
# give this process Python's own handler back, so that its children start with the default.
if signal.getsignal(signal.SIGINT) is signal.SIG_IGN:
    signal.signal(signal.SIGINT, signal.default_int_handler)

# The smallest dataset the pipeline tests need: 2 objects, 2 trajectories, 3 frames.
TINY = {"n_objects": 2, "n_trajectories": 2, "n_frames": 3, "seed": 0}


@pytest.fixture(autouse=True)
def _no_progress_env(monkeypatch: pytest.MonkeyPatch) -> None:
    # The CLI shows a generate progress bar on stderr only on a TTY or with this variable.
    monkeypatch.delenv("ENERGY_MARGIN_PROGRESS", raising=False)
    monkeypatch.delenv("ENERGY_MARGIN_DEBUG", raising=False)


@pytest.fixture(scope="session")
def tiny_dataset_source(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """One generated tiny dataset, never modified: copy it with ``tiny_dataset``."""
    out = tmp_path_factory.mktemp("source") / "tiny"
    generate_dataset("pushing", out=out, **TINY)
    return out


@pytest.fixture
def tiny_dataset(tiny_dataset_source: Path, tmp_path: Path) -> Path:
    """A private copy of the tiny dataset."""
    target = tmp_path / "tiny"
    shutil.copytree(tiny_dataset_source, target)
    return target


@pytest.fixture
def copy_dataset(tiny_dataset_source: Path, tmp_path: Path) -> Callable[[str], Path]:
    """Factory of further private copies of the tiny dataset, by directory name."""

    def _copy(name: str) -> Path:
        target = tmp_path / name
        shutil.copytree(tiny_dataset_source, target)
        return target

    return _copy


@pytest.fixture
def rewrite_frames() -> Callable[..., None]:
    """Rewrite ``frames.npz`` of a dataset with some arrays replaced (``np.savez``, uncompressed)."""

    def _rewrite(directory: Path, **replacements: np.ndarray) -> None:
        path = directory / FRAMES_FILE
        with np.load(path) as archive:
            arrays = {name: archive[name] for name in archive.files}
        arrays.update(replacements)
        with path.open("wb") as stream:
            np.savez(stream, **arrays)

    return _rewrite


def block_scene(
    n_objects: int = 1,
    *,
    shape: str = "cylinder",
    motion: str = "free",
    friction: float = 0.3,
    timestep: float = 1.0 / 120.0,
    mass: float = 0.2,
) -> Scene:
    """Objects on a ground plane at z = 0, no robot."""
    geom = Geom("box", (0.05, 0.04, 0.02)) if shape == "box" else Geom("cylinder", (0.05, 0.015))
    objects = tuple(RigidObject(f"object{i}", geom, mass) for i in range(n_objects))
    return Scene(
        objects=objects,
        robot=None,
        statics=(Geom("plane", (5.0, 5.0), name="ground"),),
        friction=friction,
        timestep=timestep,
        object_motion=motion,
    )


def resting_frame(scene: Scene, spacing: float = 0.5) -> FrameState:
    """Every object resting on the ground at x = 0, spacing, 2 spacing, ... and at rest."""
    n = scene.n_objects
    half_height = scene.objects[0].geom.size[-1]
    pos = np.zeros((n, 3))
    pos[:, 0] = spacing * np.arange(n)
    pos[:, 2] = half_height
    return FrameState(pos, np.tile([1.0, 0.0, 0.0, 0.0], (n, 1)), np.zeros((n, 6)), np.zeros(0), np.zeros(0))


@pytest.fixture
def make_block_scene() -> Callable[..., Scene]:
    return block_scene


@pytest.fixture
def make_resting_frame() -> Callable[..., FrameState]:
    return resting_frame


@pytest.fixture
def tiny_scene(tmp_path: Path) -> Path:
    """The tiny two-box scene file (and its model) in a fresh directory."""
    return write_tiny_scene(tmp_path / "scene")


class SceneFactory:
    """Writes variants of the tiny scene: ``factory(replace={old: new}, model_replace={old: new})``."""

    scene = TINY_SCENE
    model = TINY_MODEL

    def __init__(self, root: Path) -> None:
        self.root = root
        self.count = 0

    def __call__(
        self, *, replace: dict[str, str] | None = None, model_replace: dict[str, str] | None = None, append: str = ""
    ) -> Path:
        scene, model = self.scene, self.model
        for old, new in (replace or {}).items():
            assert old in scene, old
            scene = scene.replace(old, new)
        for old, new in (model_replace or {}).items():
            assert old in model, old
            model = model.replace(old, new)
        self.count += 1
        return write_tiny_scene(self.root / f"variant{self.count}", scene + append, model)


@pytest.fixture
def make_scene(tmp_path: Path) -> SceneFactory:
    """A factory of tiny-scene variants in ``tmp_path``."""
    return SceneFactory(tmp_path)

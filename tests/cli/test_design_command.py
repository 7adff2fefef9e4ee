"""``energy-margin design``: bad input in one line with nothing written, the JSON object, the learned objective."""

from __future__ import annotations

import json
import sys
from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pytest

from energy_margin import tasks
from energy_margin.analysis.frame import AnalyzerConfig
from energy_margin.analysis.run import analyze
from energy_margin.cli import main
from energy_margin.control import commands
from energy_margin.control.episodes import run_control
from energy_margin.data.dataset import load_dataset
from energy_margin.data.generate import generate_dataset
from energy_margin.design.search import PICTURE_FILE, RESULT_JSON
from energy_margin.design.verification import EpisodeVerifier
from energy_margin.learning.margin_model import fit_margin_model
from energy_margin.tasks import DesignParameter, PushingTask, get_task, register_task

TINY = ["--objects", "2", "--trajectories", "2", "--frames", "3", "--expansions", "10", "--verify", "2", "--seed", "1"]


class BrokenFamily(PushingTask):
    """A tool family whose widest pusher has a model that MuJoCo refuses."""

    name = "broken_family"

    @classmethod
    def design_space(cls) -> tuple[DesignParameter, ...]:
        return (
            DesignParameter("pusher_width", "full pusher width, m", low=0.5, high=1.0),
            DesignParameter("ground_contact", "cylinder-ground contact", choices=("geometry", "footprint")),
        )

    def make_simulator(self, n_objects, friction, drive=None, engine="mujoco"):  # type: ignore[no-untyped-def]
        if self.config.pusher_half_extents[0] > 0.48:
            import mujoco

            mujoco.MjModel.from_xml_string("<mujoco><worldbody><geom type='box' size='0 1 1'/></worldbody></mujoco>")
        return super().make_simulator(n_objects, friction, drive, engine)


class NoFamily(PushingTask):
    """Pushing that declares no tool family."""

    name = "no_family"

    @classmethod
    def design_space(cls) -> tuple[DesignParameter, ...]:
        return ()


@pytest.fixture
def broken(monkeypatch: pytest.MonkeyPatch) -> Iterator[str]:
    monkeypatch.setattr(tasks, "_REGISTRY", dict(tasks._REGISTRY))
    monkeypatch.setattr(commands, "_COMMAND_SPACES", dict(commands._COMMAND_SPACES))
    register_task(BrokenFamily)
    register_task(NoFamily)
    commands.register_command_space(BrokenFamily.name, commands.PushingCommands)
    yield BrokenFamily.name


@pytest.mark.parametrize(
    ("argv", "message"),
    [
        (
            ["--task", "pushing", "--param", "tip_length=0.05:0.1"],
            "--param tip_length: unknown pushing design parameter (a setting of task 'scooping'); known: ",
        ),
        (["--task", "pushing", "--param", "pusher_width=0.6:0.6"], "the range 0.6:0.6 is empty"),
        (["--task", "pushing", "--param", "pusher_width=0.9:0.5"], "the range 0.9:0.5 is inverted"),
        (
            ["--task", "broken_family", "--param", 'ground_contact="geometry","rim"'],
            '"rim" is not in the broken_family family (choices: "geometry", "footprint")',
        ),
        (
            ["--task", "broken_family", "--param", "pusher_width=0.5:1.0"],
            "the model of design pusher_width=1.0 does not compile: ",
        ),
        (["--task", "broken_family"], 'the model of design pusher_width=1.0, ground_contact="geometry" does not'),
        (
            ["--task", "pushing", "--param", "pusher_width=0.4:1.0", "--evaluations", "0"],
            "--evaluations must be a positive integer, got 0",
        ),
        (
            ["--task", "pushing", "--param", "pusher_width=0.4:1.0", "--verify", "0"],
            "--verify must be a positive integer, got 0",
        ),
        (
            ["--task", "pushing", "--param", "pusher_width=0.5,0.7", "--optimizer", "cma"],
            "--optimizer cma searches numeric ranges only and pusher_width is categorical; use --optimizer tpe or grid",
        ),
        (
            ["--task", "no_family"],
            "--param must give the axes, NAME=LOW:HIGH or NAME=A,B,C: task 'no_family' declares no tool family",
        ),
        (
            ["--task", "pushing", "--param", "pusher_width=0.4:1.0", "--objective", "learned"],
            "--objective learned needs --model MODEL",
        ),
    ],
)
def test_bad_input_is_one_line_and_writes_nothing(
    argv: list[str], message: str, broken: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "out"
    assert main(["design", *TINY, *argv, "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and message in err, err
    if "does not compile" in message:
        assert "size" in err  # MuJoCo's own message follows
    assert not out.exists()


@pytest.mark.parametrize(("optimizer", "package"), [("cma", "cma"), ("tpe", "optuna")])
def test_an_optimizer_that_is_not_installed_names_the_extra(
    optimizer: str, package: str, monkeypatch: pytest.MonkeyPatch, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    monkeypatch.setitem(sys.modules, package, None)  # import raises ImportError
    out = tmp_path / "out"
    argv = ["design", "--task", "pushing", "--param", "pusher_width=0.4:1.0", "--optimizer", optimizer, *TINY]
    assert main([*argv, "--out", str(out)]) == 2
    err = capsys.readouterr().err
    extra = "pip install 'energy-margin[design]'"
    assert err.strip() == f"energy-margin: error: --optimizer {optimizer} needs the {package} package: {extra}"
    assert not out.exists()


def test_json_prints_the_chosen_default_and_grid_designs(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / "push"
    argv = ["design", "--task", "pushing", "--param", "pusher_width=0.4:1.0", "--optimizer", "grid"]
    assert main([*argv, "--evaluations", "2", *TINY, "--out", str(out), "--json"]) == 0
    stdout = capsys.readouterr().out
    assert stdout.count("\n") == 1
    result = json.loads(stdout)
    assert result == json.loads((out / RESULT_JSON).read_text())
    for role in ("chosen", "default", "grid"):
        entry = result[role]
        assert set(entry["values"]) == {"pusher_width"} and role in entry["roles"]
        assert 0.0 <= entry["interval"][0] <= entry["success_rate"] <= entry["interval"][1] <= 1.0
        assert set(entry["levels"]) == {"mild", "hard"} and entry["episodes"] == 4
    assert result["grid"]["design"] == result["chosen"]["design"]  # the grid optimiser is its own grid
    assert result["picture"] == PICTURE_FILE and (out / PICTURE_FILE).stat().st_size > 0


@pytest.fixture(scope="module")
def model_file(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A small boosted-tree margin of 2-object pushing frames."""
    root = tmp_path_factory.mktemp("learned")
    generate_dataset("pushing", out=root / "train", n_objects=2, n_trajectories=4, n_frames=3, seed=2)
    analyze(root / "train", AnalyzerConfig(expansions=8), seed=0, progress=False)
    model, _ = fit_margin_model([load_dataset(root / "train")], seed=0, kind="boosting", max_iter=5, max_depth=2)
    path = root / "push2.npz"
    model.save(path)
    return path


def test_the_learned_objective(model_file: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / "learned"
    argv = ["design", "--task", "pushing", "--param", "pusher_width=0.4:1.0", "--objective", "learned"]
    argv += ["--model", str(model_file), "--optimizer", "tpe", "--evaluations", "2", *TINY, "--no-picture"]
    assert main([*argv, "--out", str(out)]) == 0
    printed = capsys.readouterr().out
    assert "(learned margin)" in printed and "chosen" in printed
    settings = json.loads((out / "design.json").read_text())
    assert settings["objective"]["kind"] == "learned" and len(settings["objective"]["model_sha256"]) == 64
    result = json.loads((out / RESULT_JSON).read_text())
    assert all(0.0 <= row["objective"] <= 1.0 for row in result["search"])
    # A model fitted on 2 objects cannot score 3.
    assert main([*argv[:-1], "--objects", "3", "--out", str(tmp_path / "three")]) == 2
    assert "fitted on 2 objects, not 3" in capsys.readouterr().err


def test_verification_episodes_are_those_of_control(tmp_path: Path) -> None:
    """Episode i of a design's verification is episode i of ``control --policy scripted --seed S``."""
    overrides = {"pusher_half_extents": [0.3, 0.1, 0.015]}
    seeds = list(enumerate(np.random.SeedSequence(4).spawn(3)))
    found = dict(EpisodeVerifier().successes(get_task("pushing"), overrides, n_objects=2, level="hard", seeds=seeds))
    summary, dataset = run_control(
        "pushing",
        n_objects=2,
        episodes=3,
        policy="scripted",
        disturbance="hard",
        seed=4,
        out=tmp_path / "control",
        task_overrides=overrides,
        score_expansions=0,
    )
    assert [found[i] for i in range(3)] == dataset.success_labels().astype(bool).tolist()
    assert summary.successes == sum(found.values())


def test_a_scene_the_episodes_cannot_control_is_refused_before_the_search(tmp_path: Path, capsys) -> None:
    # The tiny scene moves a mocap pusher: control episodes have no commands for it.
    from tiny_scene import TINY_SCENE, write_tiny_scene

    design = '\n[design]\nwidth = { geom = "pusher", attribute = "size", index = 0, low = 0.1, high = 0.2 }\n'
    scene = write_tiny_scene(tmp_path / "scene", scene=TINY_SCENE + design)
    out = tmp_path / "run"
    code = main(["design", "--scene", str(scene), "--optimizer", "grid", "--evaluations", "2", "--out", str(out)])
    assert code == 2 and not out.exists()
    error = capsys.readouterr().err
    assert error.count("\n") == 1 and "moves mocap bodies" in error


def test_the_learned_objective_is_refused_for_a_scene_family(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    # A learned margin checks the compiled model's hash: every design but the fitted one would fail.
    # Refused before the model file is read.
    from tiny_scene import TINY_SCENE, write_tiny_scene

    design = '\n[design]\nwidth = { geom = "pusher", attribute = "size", index = 0, low = 0.1, high = 0.2 }\n'
    scene = write_tiny_scene(tmp_path / "scene", scene=TINY_SCENE + design)
    out = tmp_path / "run"
    argv = ["design", "--scene", str(scene), "--objective", "learned", "--model", str(tmp_path / "push.margin")]
    assert main([*argv, "--optimizer", "grid", "--evaluations", "2", "--out", str(out)]) == 2
    error = capsys.readouterr().err
    assert error.count("\n") == 1 and "--objective learned cannot score a --scene design search" in error
    assert not out.exists()


def test_the_command_line_and_python_design_the_same_trees_by_default() -> None:
    from energy_margin.cli.app import build_parser
    from energy_margin.design.scorers import DESIGN_EXPANSIONS, TreeScorer

    args = build_parser().parse_args(
        ["design", "--task", "pushing", "--evaluations", "1", "--verify", "1", "--out", "x"]
    )
    assert args.expansions == TreeScorer().analyzer.expansions == DESIGN_EXPANSIONS
    import inspect

    from energy_margin.design.search import design_search

    defaults = inspect.signature(design_search).parameters
    assert args.trajectories == defaults["n_trajectories"].default
    assert args.frames == defaults["n_frames"].default

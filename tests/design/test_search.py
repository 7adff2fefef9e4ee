"""``design``: the search space, the optimisers, the equal-cost grid, determinism, resume, verification."""

from __future__ import annotations

import json
import math
import shutil
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest

from energy_margin import tasks
from energy_margin.analysis.frame import AnalyzerConfig
from energy_margin.control import commands
from energy_margin.design.optimizers import make_optimizer
from energy_margin.design.params import parse_param
from energy_margin.design.search import (
    EVALUATIONS_JOURNAL,
    FIGURE_FILE,
    RESULT_JSON,
    SETTINGS_FILE,
    VERIFICATION_JOURNAL,
    TreeScorer,
    design_search,
    format_result,
)
from energy_margin.design.search_result import DesignSearchResult
from energy_margin.design.space import (
    axis_values,
    even_grid,
    grid_counts,
    resolve_space,
)
from energy_margin.design.verification import EpisodeVerifier
from energy_margin.errors import EnergyMarginError, InvalidParameterError
from energy_margin.tasks import DesignParameter, PushingTask, get_task, register_task


class FamilyPushing(PushingTask):
    """Pushing with a declared tool family; a pusher wider than 0.96 m has a model that does not compile."""

    name = "family_pushing"

    @classmethod
    def design_space(cls) -> tuple[DesignParameter, ...]:
        return (
            DesignParameter("pusher_width", "full pusher width, m", low=0.5, high=1.0),
            DesignParameter("ground_contact", "cylinder-ground contact", choices=("geometry", "footprint")),
        )

    def make_simulator(self, n_objects: int, friction: float, drive: Any = None, engine: str = "mujoco") -> Any:
        if self.config.pusher_half_extents[0] > 0.48:
            import mujoco

            # MuJoCo's own message for a box of zero size.
            mujoco.MjModel.from_xml_string("<mujoco><worldbody><geom type='box' size='0 1 1'/></worldbody></mujoco>")
        return super().make_simulator(n_objects, friction, drive, engine)


class FamilylessPushing(PushingTask):
    """Pushing that declares no tool family."""

    name = "familyless_pushing"

    @classmethod
    def design_space(cls) -> tuple[DesignParameter, ...]:
        return ()


@pytest.fixture
def family(monkeypatch: pytest.MonkeyPatch) -> Iterator[str]:
    """``FamilyPushing`` (and ``FamilylessPushing``) registered (and controllable) for one test."""
    monkeypatch.setattr(tasks, "_REGISTRY", dict(tasks._REGISTRY))
    monkeypatch.setattr(commands, "_COMMAND_SPACES", dict(commands._COMMAND_SPACES))
    register_task(FamilyPushing)
    register_task(FamilylessPushing)
    commands.register_command_space(FamilyPushing.name, commands.PushingCommands)
    yield FamilyPushing.name


# The smallest search: pushing, 2 cylinders, 2 roll-outs x 3 frames, 10 expansions, 2 episodes per level.
TINY: dict[str, Any] = {"n_objects": 2, "n_trajectories": 2, "n_frames": 3, "seed": 1, "verify": 2}
PARAMS: list[tuple[str, Any]] = [("pusher_width", (0.4, 1.0))]


def _search(out: Path, *, optimizer: str = "tpe", evaluations: int = 3, **options: Any) -> dict[str, Any]:
    settings = {**TINY, **options}
    result = design_search(
        "pushing",
        settings.pop("params", PARAMS),
        optimizer=optimizer,
        evaluations=evaluations,
        out=out,
        scorer=TreeScorer(AnalyzerConfig(expansions=10)),
        verifier=EpisodeVerifier(),
        log=settings.pop("log", lambda line: None),
        **settings,
    )
    assert isinstance(result, DesignSearchResult)
    return result.to_dict()


def _essence(result: dict[str, Any]) -> Any:
    """What must not depend on workers or interruptions: every evaluation and the verification."""
    keep = ("phase", "index", "values", "objective", "per_trajectory", "rollout_successes", "error")
    rows = [*result["search"], *result["grid_evaluations"], result["default_evaluation"]]
    return (
        [{key: row.get(key) for key in keep} for row in rows],
        [
            {key: entry[key] for key in ("roles", "values", "levels", "success_rate", "interval")}
            for entry in result["verified"]
        ],
    )


@pytest.fixture(scope="module")
def reference(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, dict[str, Any]]:
    out = tmp_path_factory.mktemp("design") / "push"
    return out, _search(out)


def test_parse_param() -> None:
    assert parse_param("scoop_angle=1.0:1.5") == ("scoop_angle", (1.0, 1.5))
    assert parse_param('ground_contact="geometry","footprint"') == (
        "ground_contact",
        ["geometry", "footprint"],
    )
    assert parse_param("friction_range=[0.1,0.2],[0.2,0.4]") == ("friction_range", [[0.1, 0.2], [0.2, 0.4]])
    for text, message in [
        ("pusher_width", "expects NAME=LOW:HIGH or NAME=A,B,C"),
        ("pusher_width=0.5:0.5", "is empty"),
        ("pusher_width=0.9:0.5", "is inverted"),
        ("pusher_width=a:b", "not a range LOW:HIGH"),
        ("pusher_width=0.5,0.5", "listed twice"),
        ("pusher_width=0.5,", "neither a range"),
    ]:
        with pytest.raises(EnergyMarginError, match=message):
            parse_param(text)
    assert parse_param("pusher_width=0.5") == ("pusher_width", [0.5])
    with pytest.raises(InvalidParameterError, match="at least two values") as raised:
        resolve_space(get_task("pushing"), [parse_param("pusher_width=0.5")])
    assert raised.value.parameter == "params"


def test_resolve_space_checks_names_kinds_and_the_family(family: str) -> None:
    space = resolve_space(
        get_task("pushing"), [("pusher_width", (0.4, 1.0)), ("lateral_contact", ["geometry", "sphere"])]
    )
    assert [(p.name, p.low, p.high, p.choices, p.integer) for p in space] == [
        ("pusher_width", 0.4, 1.0, None, False),
        ("lateral_contact", None, None, ("geometry", "sphere"), False),
    ]
    # Without --param: the task's tool family.
    assert [p.name for p in resolve_space(get_task(family), [])] == ["pusher_width", "ground_contact"]
    for task, params, fixed, message in [
        ("familyless_pushing", [], {}, r"declares no tool family .*known: pusher_width, duration"),
        ("pushing", [("scoop_angle", (1.0, 1.5))], {}, r"scoop_angle: unknown pushing design parameter \(a setting"),
        ("pushing", [("pusher_width", (0.4, 1.0)), ("pusher_width", (0.5, 0.6))], {}, "given twice"),
        (
            "pushing",
            [("pusher_width", (0.4, 1.0)), ("pusher_half_extents", [[0.3, 0.1, 0.01], [0.4, 0.1, 0.01]])],
            {},
            "sets pusher_half_extents, as pusher_width does",
        ),
        ("pushing", [("drive_jitter", (0.1, 0.3))], {"drive_jitter": 0.2}, "which is fixed for every design"),
        ("pushing", [("friction_range", (0.1, 0.3))], {}, "is not a number"),
        (family, [("ground_contact", ["geometry", "sphere"])], {}, r'"sphere" is not in the family_pushing family'),
        (family, [("ground_contact", (0.0, 1.0))], {}, "is categorical in the family_pushing family"),
    ]:
        with pytest.raises(EnergyMarginError, match=message):
            resolve_space(get_task(task), params, fixed=fixed)


def test_the_even_grid_fills_the_budget_evenly() -> None:
    floats = [DesignParameter("a", "", low=0.0, high=1.0), DesignParameter("b", "", low=0.0, high=2.0)]
    assert grid_counts(floats, 6) == [3, 2]
    assert grid_counts(floats, 10) == [3, 3]
    assert grid_counts(floats, 1) == [1, 1]
    assert axis_values(floats[0], 4) == [0.125, 0.375, 0.625, 0.875]  # the centres of 4 equal cells
    choice = DesignParameter("c", "", choices=("x", "y"))
    whole = DesignParameter("n", "", low=1, high=3, integer=True)
    # A categorical axis holds at most its values, an integer one its whole numbers; the rest goes elsewhere.
    assert grid_counts([choice, whole, floats[0]], 30) == [2, 3, 5]
    assert axis_values(whole, 3) == [1, 2, 3] and axis_values(whole, 2) == [1, 3]
    assert even_grid([choice, whole], 4) == [["x", 1], ["x", 3], ["y", 1], ["y", 3]]


@pytest.mark.parametrize("name", ["cma", "tpe", "grid"])
def test_each_optimizer_is_deterministic_and_stays_in_bounds(name: str) -> None:
    space = [DesignParameter("a", "", low=-1.0, high=1.0)]
    if name != "cma":
        space.append(DesignParameter("c", "", choices=([1, 2], [3, 4], "x")))

    def run() -> list[list[Any]]:
        optimizer = make_optimizer(name, space, budget=8, seed=5)
        points = []
        for _ in range(optimizer.limit or 8):
            point = optimizer.ask()
            points.append(point)
            optimizer.tell(-abs(point[0] - 0.3))
        return points

    first = run()
    assert first == run()
    assert all(-1.0 <= point[0] <= 1.0 for point in first)
    if name != "cma":
        assert all(point[1] in ([1, 2], [3, 4], "x") for point in first)
    assert len(first) == 8  # the grid: 4 x 2 (2 of the 3 categorical values)


@pytest.mark.parametrize("optimizer", ["cma", "grid"])
def test_each_optimizer_runs_a_search(optimizer: str, tmp_path: Path) -> None:
    result = _search(tmp_path / optimizer, optimizer=optimizer, evaluations=3, verify=1, verify_all=True)
    assert result["evaluations_used"] == len(result["search"]) == 3
    assert result["settings"]["optimizer"] == optimizer
    if optimizer == "grid":
        # The grid search is its own equal-cost grid: the same designs, measured once.
        assert [row["values"] for row in result["search"]] == [row["values"] for row in result["grid_evaluations"]]
        assert [row["values"]["pusher_width"] for row in result["search"]] == [0.5, 0.7, 0.9]
        assert result["margin_evaluations"] == 4  # three designs and the default
    assert result["chosen"]["objective"] == max(row["objective"] for row in result["search"])
    assert all(set(entry["levels"]) == {"mild", "hard"} for entry in result["verified"])
    # --verify-all: every distinct visited design is verified, and the rank correlation runs over them all.
    visited = {row["design"] for row in [*result["search"], *result["grid_evaluations"], result["default_evaluation"]]}
    assert {entry["design"] for entry in result["verified"]} == visited
    assert result["correlation"]["pooled"]["n"] == len(visited)


def test_a_search_writes_its_settings_results_and_figure(reference: tuple[Path, dict[str, Any]]) -> None:
    out, result = reference
    settings = json.loads((out / SETTINGS_FILE).read_text())
    assert settings["optimizer"] == "tpe" and settings["evaluations"] == 3 and settings["seed"] == 1
    assert settings["objective"]["kind"] == "margin" and settings["objective"]["score"] == "success_score"
    assert settings["objective"]["analyzer"]["expansions"] == 10
    [axis] = settings["space"]
    assert {key: axis[key] for key in ("name", "low", "high", "integer")} == {
        "name": "pusher_width",
        "low": 0.4,
        "high": 1.0,
        "integer": False,
    }
    assert axis["doc"].startswith("full pusher width")
    assert settings["verify"] == {
        "episodes": 2,
        "disturbances": ["mild", "hard"],
        "all": False,
        "policy": "scripted",
        "frames": 2,
    }
    assert json.loads((out / RESULT_JSON).read_text()) == json.loads(json.dumps(result))
    assert (out / FIGURE_FILE).stat().st_size > 0
    # The chosen design is the search's best; the default is the task's own; the grid's is the best of its grid.
    assert result["chosen"]["roles"][0] == "chosen" and result["default"]["values"] == {"pusher_width": "default"}
    assert result["default"]["task_config"] == {}
    best_grid = max(result["grid_evaluations"], key=lambda row: row["objective"])
    assert result["grid"]["values"] == best_grid["values"]
    for entry in result["verified"]:
        mild, hard = entry["levels"]["mild"], entry["levels"]["hard"]
        assert mild["episodes"] == hard["episodes"] == 2 and entry["episodes"] == 4
        assert entry["successes"] == mild["successes"] + hard["successes"]
        assert entry["interval"][0] <= entry["success_rate"] <= entry["interval"][1]
    text = format_result(result)
    assert "chosen" in text and "mild [95 % Wilson]" in text and "tpe used 3 evaluations" in text


def test_the_equal_cost_grid(reference: tuple[Path, dict[str, Any]]) -> None:
    _, result = reference
    # As many margin evaluations as the optimiser used: 3 designs, spread over the range's 3 cells.
    assert result["grid_size"] == len(result["grid_evaluations"]) == result["evaluations_used"] == 3
    assert [row["values"]["pusher_width"] for row in result["grid_evaluations"]] == [0.5, 0.7, 0.9]
    assert result["settings"]["grid"] == {"counts": [3], "size": 3}


def test_two_workers_give_the_same_results(reference: tuple[Path, dict[str, Any]], tmp_path: Path) -> None:
    _, result = reference
    assert _essence(_search(tmp_path / "two", workers=2)) == _essence(result)


def test_an_interrupted_search_resumes_to_the_same_result(
    reference: tuple[Path, dict[str, Any]], tmp_path: Path
) -> None:
    _, result = reference
    out = tmp_path / "resumed"

    def stop_search(phase: str, index: int) -> None:
        if (phase, index) == ("search", 1):
            raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt):
        _search(out, on_evaluation=stop_search)
    assert len((out / EVALUATIONS_JOURNAL).read_text().splitlines()) == 1 + 2  # header, two evaluations

    def stop_verification(line: str) -> None:
        if line.startswith("design verify"):
            raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt):
        _search(out, log=stop_verification)
    assert (out / VERIFICATION_JOURNAL).is_file()
    lines: list[str] = []
    resumed = _search(out, log=lines.append)
    assert _essence(resumed) == _essence(result)
    assert not any(line.startswith("design tpe") for line in lines)  # nothing measured again


def test_a_resumed_search_of_two_axes_verifies_the_same_designs(tmp_path: Path) -> None:
    # Axes not in alphabetical order: the journal stores each row's values with sorted keys, so a
    # resumed run must read them back by name, not by position.
    params = [("pusher_width", (0.4, 1.0)), ("face_depth", (0.02, 0.15))]
    whole = _search(tmp_path / "whole", params=params)

    def stop_search(phase: str, index: int) -> None:
        if phase == "grid":  # every search evaluation is in the journal by then
            raise KeyboardInterrupt

    out = tmp_path / "resumed"
    with pytest.raises(KeyboardInterrupt):
        _search(out, params=params, on_evaluation=stop_search)
    resumed = _search(out, params=params)
    assert _essence(resumed) == _essence(whole)
    assert [entry["task_config"] for entry in resumed["verified"]] == [
        entry["task_config"] for entry in whole["verified"]
    ]


def test_other_settings_are_refused(reference: tuple[Path, dict[str, Any]], tmp_path: Path) -> None:
    copy = tmp_path / "copy"
    shutil.copytree(reference[0], copy)
    with pytest.raises(
        EnergyMarginError, match=r"holds a design search of other settings \(evaluations: 3 there, 4 now\)"
    ):
        _search(copy, evaluations=4)


def test_a_model_that_does_not_compile_is_refused_before_anything_is_written(family: str, tmp_path: Path) -> None:
    out = tmp_path / "broken"
    with pytest.raises(EnergyMarginError) as error:
        design_search(
            family,
            [("pusher_width", (0.5, 1.0))],
            optimizer="tpe",
            evaluations=2,
            out=out,
            verifier=EpisodeVerifier(),
            **TINY,
        )
    message = str(error.value)
    assert "the model of design pusher_width=1.0 does not compile" in message and "size" in message
    assert not out.exists()


def test_the_default_design_keeps_the_task_values(tmp_path: Path) -> None:
    result = _search(tmp_path / "scoop", params=[("drive_jitter", (0.1, 0.3))], evaluations=1, verify=1)
    assert result["default"]["values"] == {"drive_jitter": 0.2}
    assert result["grid_size"] == 1 and result["grid_evaluations"][0]["values"] == {"drive_jitter": 0.2}
    assert math.isclose(result["default"]["objective"], result["grid_evaluations"][0]["objective"])


def test_a_scene_search_takes_only_its_design_parameters(tiny_scene: Path) -> None:
    # The scene file pins its other settings (its hash): a search over them would score one model
    # under many labels.
    from energy_margin.design.space import resolve_space

    with pytest.raises(
        EnergyMarginError,
        match=r"timestep: unknown scene design parameter .*; known: none \(a scene file declares its own",
    ):
        resolve_space(
            get_task("scene", {"scene_file": str(tiny_scene)}),
            [("timestep", (0.001, 0.01))],
            fixed={"scene_file": str(tiny_scene)},
        )

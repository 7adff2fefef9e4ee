"""The Gymnasium wrapper on Gymnasium's own Pusher-v5 (a 7-joint arm and a puck on two slides)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

gymnasium = pytest.importorskip("gymnasium")

from energy_margin.cli import main  # noqa: E402
from energy_margin.data.dataset import load_dataset  # noqa: E402
from energy_margin.errors import EnergyMarginError  # noqa: E402
from energy_margin.integrations.gymnasium import MarginWrapper  # noqa: E402
from energy_margin.integrations.live_model import INFO_KEYS  # noqa: E402

CAPTURE = {"type": "distance", "body": "tips_arm", "max": 0.15}
SUCCESS = {"type": "distance", "body": "goal", "max": 0.1}


def wrapped(**options: object) -> MarginWrapper:
    settings: dict[str, object] = {"budget_s": None, "max_expansions": 15, "seed": 3}
    settings.update(options)
    return MarginWrapper(gymnasium.make("Pusher-v5"), objects="object", capture=CAPTURE, success=SUCCESS, **settings)


def starter_scene(out: Path) -> Path:
    """The starter scene file of ``energy-margin scene --from-gym Pusher-v5`` at ``out``."""
    arguments = ["scene", "--from-gym", "Pusher-v5", "--object-bodies", "object", "--out", str(out), "--no-picture"]
    assert main(arguments) == 0
    return out


def actions(n: int) -> np.ndarray:
    return np.random.default_rng(5).uniform(-2.0, 2.0, size=(n, 7))


def test_observations_are_bit_identical_with_and_without_the_wrapper() -> None:
    plain = gymnasium.make("Pusher-v5")
    wrapper = wrapped(every=1)
    first, _ = plain.reset(seed=11)
    second, info = wrapper.reset(seed=11)
    assert np.array_equal(first, second)
    assert set(info["energy_margin"]) == set(INFO_KEYS)
    scored = 0
    for action in actions(12):
        a = plain.step(action)
        b = wrapper.step(action)
        assert np.array_equal(a[0], b[0])
        assert a[1] == b[1]
        assert "energy_margin" not in a[4]
        scored += "energy_margin" in b[4]
    assert scored == 12
    # The environment's own random numbers are untouched: the next episode starts alike too.
    assert np.array_equal(plain.reset()[0], wrapper.reset()[0])


def test_info_holds_the_scores_every_k_steps() -> None:
    wrapper = wrapped(every=3)
    wrapper.reset(seed=0)
    seen = []
    for step, action in enumerate(actions(7), start=1):
        info = wrapper.step(action)[4]
        if "energy_margin" in info:
            seen.append(step)
            margin = info["energy_margin"]
            assert set(margin) == set(INFO_KEYS)
            assert 0.0 <= margin["capture_score"] <= 1.0 and 0.0 <= margin["success_score"] <= 1.0
            assert margin["expansions"] == 15 and margin["stopped_by"] == "max_expansions"
            assert margin["ms"] > 0
    assert seen == [3, 6]


def test_fixed_expansions_give_identical_scores_for_the_same_seed() -> None:
    runs = []
    for _ in range(2):
        wrapper = wrapped(every=2)
        wrapper.reset(seed=4)
        runs.append([wrapper.step(a)[4].get("energy_margin") for a in actions(6)])
    strip = [[None if m is None else {k: v for k, v in m.items() if k != "ms"} for m in run] for run in runs]
    assert strip[0] == strip[1]
    assert strip[0][1] is not None and strip[0][1]["seed"] != strip[0][3]["seed"]


def test_a_wall_clock_budget_stops_growth() -> None:
    wrapper = wrapped(budget_s=0.02, max_expansions=100_000)
    wrapper.reset(seed=0)
    margin = wrapper.step(actions(1)[0])[4]["energy_margin"]
    assert margin["stopped_by"] == "budget"
    assert margin["ms"] < 200


def test_hold_still_keeps_the_robot_in_place_during_propagation() -> None:
    moved, coasted = {}, {}
    for hold in ("action", "still", "coasting"):
        wrapper = wrapped(hold=hold)
        wrapper.reset(seed=2)
        for action in actions(3):
            wrapper.step(action)
        scorer = wrapper.scorer
        data = wrapper.unwrapped.data
        data_ctrl = np.array(data.ctrl)
        state = scorer.frame(data)
        simulator = scorer.simulator
        simulator.reset(state)
        simulator.data.ctrl[:] = data_ctrl
        before, velocity = simulator.robot_positions(), simulator.robot_velocities()
        simulator.step(20)
        moved[hold] = float(np.max(np.abs(simulator.robot_positions() - before)))
        elapsed = 20 * float(simulator.model.opt.timestep)
        coasted[hold] = float(np.max(np.abs(simulator.robot_positions() - (before + velocity * elapsed))))
    assert moved["action"] > 1e-3
    assert moved["still"] < 1e-6
    # Coasting: the arm goes on at the frame's joint velocities, whatever its actuators and contacts do.
    assert moved["coasting"] > 1e-3
    assert coasted["coasting"] < 1e-4 * moved["coasting"] < coasted["action"]


def test_recorded_episode_becomes_a_dataset(tmp_path: Path) -> None:
    starter_scene(tmp_path / "pusher.toml")
    wrapper = wrapped(every=0, record=True)
    wrapper.reset(seed=1)
    for action in actions(20):
        wrapper.step(action)
    episode = wrapper.save_episode(tmp_path / "episode.npz")
    rows = np.load(episode)
    assert rows["qpos"].shape == (21, 11) and rows["time"][0] == 0.0
    assert np.allclose(np.diff(rows["time"]), wrapper.unwrapped.dt)
    # MuJoCo's warning counts ride along, for record to refuse a roll-out that went wrong.
    assert rows["mujoco_warnings"].shape == (21, 7) and not rows["mujoco_warnings"].any()
    out = tmp_path / "dataset"
    assert (
        main(["record", "--scene", str(tmp_path / "pusher.toml"), str(episode), "--frames", "5", "--out", str(out)])
        == 0
    )
    dataset = load_dataset(out)
    assert dataset.n_frames == 5 and dataset.n_objects == 1
    # The last frame is the episode's last state: the puck where the wrapper saw it.
    final = dataset.frame(0, 4)
    assert np.allclose(final.object_pos[0], wrapper.unwrapped.data.xpos[wrapper.unwrapped.model.body("object").id])


def test_save_episode_needs_recording() -> None:
    wrapper = wrapped()
    with pytest.raises(EnergyMarginError, match="record=True"):
        wrapper.save_episode("x.npz")


@pytest.mark.parametrize(
    ("arguments", "message"),
    [
        ({"objects": "cube*"}, r"^Pusher-v5: objects.bodies: no body 'cube\*' in Pusher-v5$"),
        ({"capture": {"type": "distance", "body": "hand", "max": 0.1}}, r"capture.region.body: no body 'hand'"),
        ({"success": {"type": "distance", "site": "goal", "max": 0.1}}, r"success.region.site: no site 'goal'"),
        ({"capture": {"type": "sphere"}}, r"capture.region.type: unknown region type 'sphere'"),
        ({"objects": None}, r"^objects is missing"),
        ({"every": -1}, r"every"),
        ({"hold": "freeze"}, r"hold"),
    ],
)
def test_bad_arguments_are_one_line(arguments: dict[str, object], message: str) -> None:
    settings: dict[str, object] = {"objects": "object", "capture": CAPTURE, "success": SUCCESS}
    settings.update(arguments)
    with pytest.raises((EnergyMarginError, ValueError), match=message) as raised:
        MarginWrapper(gymnasium.make("Pusher-v5"), **settings)  # type: ignore[arg-type]
    assert "\n" not in str(raised.value)


def test_an_environment_without_a_mujoco_model_is_refused() -> None:
    with pytest.raises(EnergyMarginError, match=r"CartPoleEnv\) has no MuJoCo model"):
        MarginWrapper(gymnasium.make("CartPole-v1"), objects="x", capture=CAPTURE, success=SUCCESS)


def test_a_scene_file_gives_the_tables(tmp_path: Path) -> None:
    starter_scene(tmp_path / "p.toml")
    wrapper = MarginWrapper(gymnasium.make("Pusher-v5"), scene=tmp_path / "p.toml", budget_s=None, max_expansions=5)
    wrapper.reset(seed=0)
    assert "energy_margin" in wrapper.step(actions(1)[0])[4]
    assert wrapper.scorer.object_names == ("object",)


@pytest.fixture(scope="module")
def pusher_model(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A boosted-tree margin model fitted to 4 recorded Pusher episodes analysed with 10 expansions per frame."""
    from energy_margin.analysis.frame import AnalyzerConfig
    from energy_margin.analysis.run import analyze
    from energy_margin.data.record import record_dataset
    from energy_margin.integrations.gym_scene import scene_from_environment
    from energy_margin.learning.margin_model import fit_margin_model

    directory = tmp_path_factory.mktemp("pusher-model")
    wrapper = wrapped(every=0, record=True)
    scene = scene_from_environment(wrapper, objects="object", out=directory / "pusher.toml").scene_file
    episodes = []
    for episode in range(4):
        wrapper.reset(seed=episode)
        for action in actions(10):
            wrapper.step(action)
        episodes.append(wrapper.save_episode(directory / f"episode_{episode}.npz"))
    record_dataset(scene, episodes, n_frames=4, out=directory / "dataset")
    analyze(directory / "dataset", AnalyzerConfig(expansions=10), seed=0, workers=1)
    model, _ = fit_margin_model([load_dataset(directory / "dataset")], seed=0, kind="boosting", max_iter=5, max_depth=2)
    model.save(directory / "model.npz")
    return directory / "model.npz"


def test_a_learned_margin_scores_without_a_tree(pusher_model: Path) -> None:
    wrapper = wrapped(model=pusher_model, every=1)
    _, info = wrapper.reset(seed=0)
    margin = wrapper.step(actions(1)[0])[4]["energy_margin"]
    assert margin["stopped_by"] == "learned" and margin["expansions"] == 0 and margin["nodes"] == 0
    assert 0.0 <= margin["capture_score"] <= 1.0 and 0.0 <= margin["success_score"] <= 1.0
    assert info["energy_margin"]["stopped_by"] == "learned"


def test_a_margin_model_of_another_task_is_refused(tmp_path: Path, pusher_model: Path) -> None:
    with pytest.raises(EnergyMarginError, match="does not exist"):
        wrapped(model=tmp_path / "missing.npz")
    with pytest.raises(EnergyMarginError, match="margin model file or a MarginModel"):
        wrapped(model=42)
    # Fitted on Pusher-v5's model; an environment whose model differs (a heavier puck) refuses it.
    env = gymnasium.make("Pusher-v5")
    env.unwrapped.model.body_mass[env.unwrapped.model.body("object").id] *= 2.0
    with pytest.raises(EnergyMarginError, match=r"^the margin model was fitted on another compiled model"):
        MarginWrapper(env, objects="object", capture=CAPTURE, success=SUCCESS, model=pusher_model)


@pytest.mark.parametrize("hold", ["still", "coasting"])
def test_hold_still_is_the_scene_option_of_the_simulator(hold: str) -> None:
    wrapper = wrapped(hold=hold)
    assert wrapper.scorer.task.loaded.spec.motion.robot == hold
    assert wrapper.scorer.simulator.still == (hold == "still")
    assert wrapper.scorer.simulator.coasting == (hold == "coasting")
    # The environment's own model is untouched by the armature of the scorer's copy.
    assert float(wrapper.unwrapped.model.dof_armature.max()) < 1e3


def test_the_tree_budget_keeps_a_reserve_for_the_measured_overrun() -> None:
    wrapper = wrapped(budget_s=0.02, max_expansions=100_000)
    scorer = wrapper.scorer
    assert scorer.tree_budget() == pytest.approx(0.02)
    wrapper.reset(seed=0)
    for action in actions(3):
        margin = wrapper.step(action)[4]["energy_margin"]
        assert margin["stopped_by"] == "budget"
    # Every call's overrun of its tree's budget is kept; the next tree gets the budget less the largest.
    assert len(scorer._overruns) == 4 and all(overrun >= 0 for overrun in scorer._overruns)
    assert scorer.tree_budget() == pytest.approx(max(0.02 - max(scorer._overruns), 0.01))
    scorer._overruns[:] = [0.003, 0.05]
    assert scorer.tree_budget() == pytest.approx(0.01)  # never less than half the budget
    scorer._overruns[:] = [0.003, 0.001]
    assert scorer.tree_budget() == pytest.approx(0.017)
    assert wrapped(budget_s=None).scorer.tree_budget() is None


def test_a_scene_files_randomisation_leaves_the_model_as_it_is(tmp_path: Path) -> None:
    starter_scene(tmp_path / "p.toml")
    scene = tmp_path / "p.toml"
    scene.write_text(scene.read_text() + "\n[randomize]\nfriction = [0.1, 0.2]\nmass_scale = [2.0, 3.0]\n")
    env = gymnasium.make("Pusher-v5")
    puck = env.unwrapped.model.body("object").id
    env.unwrapped.model.geom_friction[env.unwrapped.model.geom_bodyid == puck, 0] = 0.5  # the others keep 0.8
    wrapper = MarginWrapper(env, scene=scene, budget_s=None, max_expansions=5)
    model = wrapper.scorer.simulator.model
    assert np.array_equal(model.geom_friction, wrapper.unwrapped.model.geom_friction)
    assert np.array_equal(model.body_mass, wrapper.unwrapped.model.body_mass)
    with pytest.raises(EnergyMarginError, match="give either scene or objects, capture, not both"):
        MarginWrapper(gymnasium.make("Pusher-v5"), scene=scene, objects="object", capture=CAPTURE)


def test_a_not_region_is_a_region_not_a_set_table() -> None:
    """A ``not`` region holds a ``region`` key of its own: it is still the set's region, not its table."""
    outside = {"type": "not", "region": {"type": "distance", "body": "goal", "max": 0.05}}
    wrapper = MarginWrapper(
        gymnasium.make("Pusher-v5"), objects="object", capture=CAPTURE, success=outside, budget_s=None, max_expansions=5
    )
    assert wrapper.scorer.task.loaded.spec.success == outside
    with_at_least = MarginWrapper(
        gymnasium.make("Pusher-v5"), objects="object", capture={"region": CAPTURE, "at_least": 1}, success=SUCCESS
    )
    assert with_at_least.scorer.task.loaded.spec.capture_at_least == 1


def test_a_calibration_adds_the_alarm(tmp_path: Path) -> None:
    from energy_margin.evaluation.monitor import MonitorCalibration, write_calibration

    settings = {"alpha": 0.1, "rank": 1, "n_successes": 9, "n_trajectories": 9, "scorer": "margin"}
    always = MonitorCalibration(threshold=2.0, score="success", start_frame=1, **settings)  # scores are <= 1
    # Every call is below from call 0 on; the alarm waits for the second (call 1) or a fourth (none in three).
    second = MonitorCalibration(threshold=2.0, score="min", start_frame=0, persistence=2, **settings)
    never = MonitorCalibration(threshold=2.0, score="min", start_frame=0, persistence=4, **settings)
    path = tmp_path / "alarm.json"
    write_calibration(path, [always])
    cases = ((path, [False, True, True]), (second, [False, True, True]), (never, [False, False, False]))
    for calibration, expected in cases:
        wrapper = wrapped(every=1, max_expansions=3, calibration=calibration)
        seen = [wrapper.reset(seed=0)[1]["energy_margin"]["alarm"]]
        seen += [wrapper.step(action)[4]["energy_margin"]["alarm"] for action in actions(2)]
        assert seen == expected
    assert "alarm" not in wrapped(every=1, max_expansions=3).reset(seed=0)[1]["energy_margin"]


@pytest.mark.parametrize("hold", ["action", "still"])
def test_live_calls_simulate_the_analysis_model_and_score_as_the_full_one(hold: str) -> None:
    from energy_margin.analysis.frame import AnalyzerConfig

    scores = {}
    for model in ("pruned", "full"):
        wrapper = wrapped(hold=hold, config=AnalyzerConfig(analysis_model=model))
        wrapper.reset(seed=2)
        margins = [wrapper.step(action)[4]["energy_margin"] for action in actions(3)]
        scores[model] = [(m["capture_score"], m["success_score"], m["nodes"]) for m in margins]
        report = wrapper.scorer.simulator.pruned_contacts
        if model == "full":
            assert report is None
        else:
            # The arm's links no longer test against each other (nor, held still, against the table).
            assert report.applied and report.robot_geoms > 0 and report.robot_still == (hold == "still")
    # The arm touches itself nowhere in these trees: the same scores to the last bit.
    assert scores["pruned"] == scores["full"]


def test_the_held_command_is_set_once_per_propagation_and_steps_as_set_every_period(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    import energy_margin.planning.propagate as propagate

    read, command = propagate._read, propagate.command_robot
    seen: dict[str, dict[str, list]] = {}
    for variant in ("once", "every period"):
        record: dict[str, list] = {"positions": [], "commands": [], "scores": []}
        seen[variant] = record

        def reading(simulator: object, *, needs_energy: bool, record: dict[str, list] = record) -> object:
            outcome = read(simulator, needs_energy=needs_energy)
            record["positions"].append(outcome.pos.copy())
            return outcome

        def commanding(*arguments: object, record: dict[str, list] = record) -> None:
            record["commands"].append(1)
            command(*arguments)

        monkeypatch.setattr(propagate, "_read", reading)
        monkeypatch.setattr(propagate, "command_robot", commanding)
        wrapper = wrapped(every=1)
        if variant == "every period":  # the behaviour before: the scene's default control period
            wrapper.scorer.task.control_period = 0.01
        else:
            assert wrapper.scorer.task.control_period is None
        wrapper.reset(seed=2)
        for action in actions(3):
            margin = wrapper.step(action)[4]["energy_margin"]
            record["scores"].append((margin["capture_score"], margin["success_score"], margin["nodes"]))
    once, every = seen["once"], seen["every period"]
    # One command per propagation instead of one per step, and the same tree states to the last bit.
    assert len(once["commands"]) == len(once["positions"]) > 0
    assert len(every["commands"]) > 2 * len(every["positions"])
    assert once["scores"] == every["scores"]
    assert len(once["positions"]) == len(every["positions"])
    assert all(np.array_equal(a, b) for a, b in zip(once["positions"], every["positions"], strict=True))


@pytest.mark.parametrize(("hold", "robot"), [("action", "declared"), ("coasting", "coasting")])
def test_a_scene_following_recorded_paths_holds_its_command_live(tmp_path: Path, hold: str, robot: str) -> None:
    """A live state has no recording: the robot holds its last action, or does what ``hold`` says."""
    scene = starter_scene(tmp_path / "p.toml")
    scene.write_text(scene.read_text().replace("[motion]\n", '[motion]\nrobot = "recorded"\n', 1))
    wrapper = MarginWrapper(gymnasium.make("Pusher-v5"), scene=scene, hold=hold, budget_s=None, max_expansions=5)
    task = wrapper.scorer.task
    assert task.loaded.spec.motion.robot == robot and task.drive_size() == 2
    wrapper.reset(seed=0)
    margin = wrapper.step(actions(1)[0])[4]["energy_margin"]
    assert 0.0 <= margin["capture_score"] <= 1.0


def test_a_policy_s_continuations_run_to_the_time_limit_and_leave_the_episode_alone() -> None:
    """Pusher-v5's time limit is 100 steps of 0.05 s: every continuation's last command falls in its last 0.05 s."""
    calls: list[list[float]] = []  # the times of each copy's calls

    class Still:
        def __call__(self, data) -> np.ndarray:  # type: ignore[no-untyped-def]
            calls[-1].append(float(data.time))
            return np.zeros(7)

        def __deepcopy__(self, memo: dict) -> Still:
            calls.append([])
            return self

    plain = gymnasium.make("Pusher-v5")
    wrapper = wrapped(every=4, policy=Still(), continuation=2)
    assert wrapper.session.episode_steps == 100 and wrapper.session.step_s == pytest.approx(0.05)
    assert wrapper.scorer.policy_period_s == pytest.approx(0.05)
    first, info = wrapper.reset(seed=2)
    assert np.array_equal(first, plain.reset(seed=2)[0])
    assert info["energy_margin"]["continuation_ms"] > 0.0
    for action in actions(4):
        observation, *_ = wrapper.step(action)
        assert np.array_equal(observation, plain.step(action)[0])
    assert len(calls) >= 2
    for times in calls:  # one command every 0.05 s, the last one within a period of the time limit
        np.testing.assert_allclose(np.diff(times), 0.05, atol=1e-9)
        assert times[-1] < 5.0 <= times[-1] + 0.05 + 1e-9

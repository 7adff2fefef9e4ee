"""Generation never writes frames that the dataset check refuses: a too-deep draw is redrawn."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from energy_margin import compat
from energy_margin.cli import main
from energy_margin.data import generate as generate_module
from energy_margin.data.dataset import load_dataset
from energy_margin.data.generate import MAX_DRAWS, REDRAWN_KEY, generate_dataset, replay_trajectory, trajectory_rng
from energy_margin.data.validation import check_dataset
from energy_margin.errors import EnergyMarginError
from releases import CROWD_REDRAWN, for_release


def test_a_crowd_of_twenty_cylinders_is_redrawn_where_it_sinks_into_itself(tmp_path: Path) -> None:
    # Seed 43's trajectory 12 piles 20 cylinders 28 mm deep into a wall (limit 25 mm) with MuJoCo
    # 4.0.0, which then throws one a metre past the workspace; MuJoCo 3.3.0's contacts sink
    # trajectories 2 and 3 instead. Each is redrawn, with the reason.
    expected = for_release(CROWD_REDRAWN, "the redrawn trajectories")
    dataset = generate_dataset("pushing", n_objects=20, n_trajectories=13, n_frames=10, seed=43, out=tmp_path / "d")
    redrawn = dataset.metadata[REDRAWN_KEY]
    assert {index: entry["draw"] for index, entry in redrawn.items()} == expected
    assert all(len(entry["reasons"]) == entry["draw"] for entry in redrawn.values())
    assert all(reason.startswith("frame ") for entry in redrawn.values() for reason in entry["reasons"])
    assert check_dataset(tmp_path / "d") == []
    for trajectory in map(int, expected):
        first_draw = generate_module.record_trajectory(
            dataset.task, 20, 10, trajectory_rng(43, 13, trajectory), check_overlaps=False
        )
        assert not np.array_equal(first_draw["object_pos"], dataset.arrays["object_pos"][trajectory])
        with pytest.raises(generate_module.RefusedDrawError):
            generate_module.record_trajectory(
                dataset.task, 20, 10, trajectory_rng(43, 13, trajectory), check_overlaps=True
            )


def _refuse_first_draws(monkeypatch: pytest.MonkeyPatch, refused: int) -> list[int]:
    """Make the overlap check refuse the first ``refused`` draws of trajectory 1 (counting the draws)."""
    calls: list[int] = []
    real = generate_module.record_trajectory

    def record(task, n_objects, n_frames, rng, *, engine="mujoco", check_overlaps=False):  # type: ignore[no-untyped-def]
        record = real(task, n_objects, n_frames, rng, engine=engine, check_overlaps=check_overlaps)
        if 1 <= len(calls) <= refused:  # the first call is trajectory 0's
            calls.append(1)
            raise generate_module.DeepOverlapError("frame 0: object 0 overlaps object 1 by 30.0 mm (limit 25.0 mm)")
        calls.append(0)
        return record

    monkeypatch.setattr(generate_module, "record_trajectory", record)
    return calls


def test_a_redrawn_trajectory_is_recorded_and_replays(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    plain = generate_dataset("pushing", n_objects=2, n_trajectories=3, n_frames=3, seed=5, out=tmp_path / "plain")
    _refuse_first_draws(monkeypatch, refused=2)
    redrawn = generate_dataset("pushing", n_objects=2, n_trajectories=3, n_frames=3, seed=5, out=tmp_path / "r")
    assert REDRAWN_KEY not in plain.metadata
    reason = "frame 0: object 0 overlaps object 1 by 30.0 mm (limit 25.0 mm)"
    assert redrawn.metadata[REDRAWN_KEY] == {"1": {"draw": 2, "reasons": [reason, reason]}}
    for key in ("object_pos", "drive"):
        assert np.array_equal(redrawn.arrays[key][[0, 2]], plain.arrays[key][[0, 2]])
        assert not np.array_equal(redrawn.arrays[key][1], plain.arrays[key][1])
    monkeypatch.undo()
    reloaded = load_dataset(tmp_path / "r")
    steps = reloaded.task.frame_steps(3)
    replayed = [state for _, state in replay_trajectory(reloaded, 1, steps)]
    for frame, state in enumerate(replayed):
        assert np.array_equal(state.object_pos, reloaded.arrays["object_pos"][1, frame])


def test_generation_gives_up_in_one_line_when_every_draw_overlaps(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    _refuse_first_draws(monkeypatch, refused=MAX_DRAWS)
    with pytest.raises(EnergyMarginError, match=f"trajectory 1: each of {MAX_DRAWS} draws") as error:
        generate_dataset("pushing", n_objects=2, n_trajectories=3, n_frames=3, seed=5, out=tmp_path / "r")
    assert "\n" not in str(error.value)
    assert str(error.value).count("cannot generate") == 1
    assert not (tmp_path / "r").exists()


def test_a_roll_out_that_blows_up_is_drawn_again_then_refused(make_scene, tmp_path, capsys, monkeypatch) -> None:
    # MuJoCo restarts a blown-up simulation from the reference state by itself: without the check,
    # the restarted frames would be written as data. MuJoCo's own log (MUJOCO_LOG.TXT in the
    # working directory) is not written: its messages stay with the command.
    monkeypatch.chdir(tmp_path)
    scene = make_scene(model_replace={'<option timestep="0.01"/>': '<option timestep="0.01" gravity="0 0 -1e200"/>'})
    out = tmp_path / "blown"
    code = main(["generate", "--scene", str(scene), "--trajectories", "2", "--frames", "3", "--out", str(out)])
    assert code == 2 and not out.exists()
    error = capsys.readouterr().err.strip().splitlines()
    if compat.compile_refuses_warnings():
        # Before MuJoCo 3.10 the compiler's own first step already fails: the scene is refused as it loads.
        assert len(error) == 1 and error[0].startswith(f"energy-margin: error: {scene}:2: mjcf: model.xml does not")
        assert error[0].endswith(
            "compile: Nan, Inf or huge value in QACC at DOF 2. The simulation is unstable. Time = 0.0000."
        )
        return
    assert error == [
        "energy-margin: error: cannot generate scene trajectory 0: each of 8 draws failed (the last: MuJoCo warned "
        "mjWARN_BADQACC 1x: a NaN, infinite or huge acceleration, and reset the simulation); the simulation is "
        "unstable: a smaller time step (<option timestep>), another integrator (implicit, RK4) or softer "
        "contacts in the model may keep it stable"
    ]
    if compat.has_warning_hook():
        assert not (tmp_path / "MUJOCO_LOG.TXT").exists()


def test_generation_stops_in_one_line_when_most_draws_fail(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    # Two of every three draws leave the bounds: after ten failures generation blames the scene.
    real = generate_module.record_trajectory
    calls: list[int] = []

    def record(task, n_objects, n_frames, rng, *, engine="mujoco", check_overlaps=False):  # type: ignore[no-untyped-def]
        calls.append(1)
        if len(calls) % 3:
            raise generate_module.UnphysicalError(
                "frame 4: object 0 at (55, 66, 1.9) m lies outside the bounds (-1.5, -1.5, -0.1) to (1.5, 1.5, 2) m"
            )
        return real(task, n_objects, n_frames, rng, engine=engine, check_overlaps=check_overlaps)

    monkeypatch.setattr(generate_module, "record_trajectory", record)
    with pytest.raises(EnergyMarginError) as error:
        generate_dataset("pushing", n_objects=2, n_trajectories=10, n_frames=3, seed=5, out=tmp_path / "r")
    message = str(error.value)
    assert message.startswith("cannot generate pushing trajectories: 10 of 14 draws failed, most for the same cause")
    assert "objects leave the scene's [bounds]" in message and "\n" not in message
    assert not (tmp_path / "r").exists()

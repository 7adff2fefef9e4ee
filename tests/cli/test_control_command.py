"""``energy-margin control``: a summary, JSON, a dataset that analyze reads, one-line errors."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from energy_margin.cli import main

SHORT = [
    "--set",
    "duration=0.3",
    "--samples",
    "3",
    "--horizon",
    "2",
    "--period",
    "0.05",
    "--frames",
    "3",
    "--expansions",
    "2",
    "--no-progress",
]


def _run(args: list[str], capsys: pytest.CaptureFixture[str]) -> tuple[int, str, str]:
    code = main(args)
    captured = capsys.readouterr()
    return code, captured.out, captured.err


def test_control_prints_a_summary_and_writes_a_dataset(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / "run"
    code, text, _ = _run(
        ["control", "--objects", "2", "--episodes", "2", "--policy", "heuristic", "--out", str(out), *SHORT], capsys
    )
    assert code == 0
    assert "95 % Wilson interval" in text and "ms per decision" in text and "mean capture score" in text
    code, _, err = _run(["analyze", str(out), "--expansions", "5", "--no-progress"], capsys)
    assert code == 0, err
    code, text, _ = _run(["evaluate", str(out), "--json"], capsys)
    assert code == 0 and "capture" in text


def test_control_json(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    code, text, _ = _run(
        [
            "control",
            "--objects",
            "2",
            "--episodes",
            "2",
            "--policy",
            "scripted",
            "--json",
            "--out",
            str(tmp_path / "r"),
            *SHORT,
        ],
        capsys,
    )
    assert code == 0
    summary = json.loads(text)
    assert summary["policy"] == "scripted" and summary["episodes"] == 2
    assert summary["seconds_per_decision"] is None


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["--policy", "learned"], "--policy learned needs --model"),
        (["--policy", "task", "--model", "m.npz"], "--model is only for --policy learned"),
        (["--task", "scene"], "pass --scene SCENE.toml"),
        (["--task", "nosuch"], "cannot be controlled"),
        (["--period", "0"], "--period must be a finite number > 0, got 0.0"),
    ],
)
def test_control_errors_are_one_line(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], args: list[str], message: str
) -> None:
    code, _, err = _run(["control", "--out", str(tmp_path / "r"), *SHORT, *args], capsys)
    assert code == 2
    assert message in err
    assert len(err.strip().splitlines()) == 1
    assert "Traceback" not in err


def test_control_lookahead_is_run_and_saved(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / "ahead"
    args = ["control", "--objects", "2", "--episodes", "1", "--policy", "task", "--lookahead", "3", "--out", str(out)]
    code, _, err = _run([*args, *SHORT], capsys)
    assert code == 0, err
    settings = json.loads((out / "control.json").read_text())["settings"]
    assert settings["controller"]["lookahead"] == 3
    with pytest.raises(SystemExit) as exited:
        main(["control", "--lookahead", "-1", "--out", str(tmp_path / "bad"), *SHORT])
    assert exited.value.code == 2
    assert "--lookahead: expected an integer >= 0, got -1" in capsys.readouterr().err
    assert not (tmp_path / "bad").exists()


def test_control_says_which_episodes_it_left_out_of_the_dataset(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    from energy_margin.control import episode_dataset

    # The check itself is tested with real impossible frames (tests/control/test_episode_dataset.py).
    monkeypatch.setattr(episode_dataset, "unphysical_trajectories", lambda dataset: {1: "frame 2: too deep"})
    arguments = ["control", "--objects", "2", "--episodes", "3", "--policy", "scripted", *SHORT]
    code, text, _ = _run([*arguments, "--out", str(tmp_path / "r")], capsys)
    assert code == 0
    assert (
        "left out of the dataset 1 episode(s) with a physically impossible frame (listed in dataset.json's "
        "dropped; the first: episode 1: frame 2: too deep); the summary counts every episode"
    ) in text
    assert "3 episodes" in text
    code, text, _ = _run([*arguments, "--json", "--out", str(tmp_path / "j")], capsys)
    assert json.loads(text)["dropped"] == [{"rollout": "episode 1", "reason": "frame 2: too deep"}]

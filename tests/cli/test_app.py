from __future__ import annotations

import argparse
import json
import subprocess
import sys
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest

from energy_margin import __version__
from energy_margin.analysis.frame import AnalyzerConfig
from energy_margin.cli import main
from energy_margin.data.dataset import FRAMES_FILE, Dataset

REQUIRED = {
    "capture_ap",
    "success_ap",
    "capture_positive_rate",
    "success_positive_rate",
    "n_frames",
    "n_trajectories",
    "runtime_per_frame_s",
    "baselines",
}
GENERATE = ["generate", "--task", "pushing", "--objects", "2", "--trajectories", "2", "--frames", "3", "--seed", "0"]


def run_cli(args: list[str], capsys: pytest.CaptureFixture[str]) -> tuple[int, str, str]:
    """Run ``main`` in this process: (exit status, stdout, stderr)."""
    try:
        code = main(args)
    except SystemExit as exit_:
        code = exit_.code if isinstance(exit_.code, int) else 1
    captured = capsys.readouterr()
    return code, captured.out, captured.err


def snapshot(root: Path) -> dict[str, bytes]:
    """Every file and directory under ``root`` (hidden ones included)."""
    return {str(p.relative_to(root)): (p.read_bytes() if p.is_file() else b"<dir>") for p in sorted(root.rglob("*"))}


def assert_one_error_line(code: int, err: str, *, expected_code: int = 2) -> None:
    assert code == expected_code, err
    lines = err.splitlines()
    assert len(lines) == 1, err
    assert lines[0].startswith("energy-margin"), err
    assert "error:" in lines[0]
    assert "Traceback" not in err


# ---------------------------------------------------------------- help and version


def test_help_exits_zero(capsys: pytest.CaptureFixture[str]) -> None:
    code, out, _ = run_cli(["--help"], capsys)
    assert code == 0
    assert "generate" in out
    assert "analyze" in out
    assert "evaluate" in out
    code, out, _ = run_cli(["analyze", "--help"], capsys)
    assert code == 0
    assert "--expansions" in out
    assert "--workers" in out


def test_version(capsys: pytest.CaptureFixture[str]) -> None:
    code, out, _ = run_cli(["--version"], capsys)
    assert code == 0
    assert out.strip() == f"energy-margin {__version__}"


# ---------------------------------------------------------------- the whole pipeline


def test_generate_analyze_evaluate(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    data = tmp_path / "push"
    code, out, err = run_cli([*GENERATE, "--out", str(data)], capsys)
    assert code == 0, err
    assert err == ""
    assert "2 trajectories x 3 frames, 2 objects" in out
    assert sorted(p.name for p in data.iterdir()) == ["dataset.json", "frames.npz"]

    code, out, err = run_cli(["analyze", str(data), "--expansions", "30", "--seed", "1", "--no-progress"], capsys)
    assert code == 0, err
    assert err == ""
    assert out.strip() == f"wrote {data / 'scores.csv'}"
    lines = (data / "scores.csv").read_text().splitlines()
    assert len(lines) == 7
    assert all(line.split(",")[5] == "30" for line in lines[1:])

    code, out, err = run_cli(["evaluate", str(data), "--json"], capsys)
    assert code == 0, err
    result = json.loads(out)
    assert set(result) >= REQUIRED
    assert "current_state" in result["baselines"]
    assert result["n_frames"] == 6
    assert result["n_trajectories"] == 2

    code, out, _ = run_cli(["evaluate", str(data), "--capture-window", "1", "--success-frames", "2"], capsys)
    assert code == 0
    assert "capture AP, k-hat=1" in out
    assert "success AP, last 2 frames" in out


def test_analyze_options_reach_the_configuration(tiny_dataset: Path, capsys: pytest.CaptureFixture[str]) -> None:
    args = ["analyze", str(tiny_dataset), "--nodes", "8", "--cost", "energy", "--lambda", "2.5", "--no-progress"]
    code, _, err = run_cli(args, capsys)
    assert code == 0, err
    description = json.loads((tiny_dataset / "analysis.json").read_text())
    assert description["analyzer"]["expansions"] is None
    assert description["analyzer"]["nodes"] == 8
    assert description["analyzer"]["cost"] == "energy"
    assert description["likelihood_lambda"] == 2.5
    # A different configuration is refused, then accepted with --overwrite.
    code, _, err = run_cli(["analyze", str(tiny_dataset), "--expansions", "5", "--no-progress"], capsys)
    assert_one_error_line(code, err)
    assert "--overwrite" in err
    code, _, err = run_cli(["analyze", str(tiny_dataset), "--expansions", "5", "--no-progress", "--overwrite"], capsys)
    assert code == 0, err
    assert json.loads((tiny_dataset / "analysis.json").read_text())["analyzer"]["expansions"] == 5


def test_default_budget_is_300_iterations(
    tiny_dataset: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    seen: dict[str, AnalyzerConfig] = {}

    def fake_analyze(dataset: Dataset, config: AnalyzerConfig, **kwargs: object) -> Path:
        seen["config"] = config
        assert dataset.path is not None
        return dataset.path / "scores.csv"

    monkeypatch.setattr("energy_margin.analysis.run.analyze_dataset", fake_analyze)
    code, _, err = run_cli(["analyze", str(tiny_dataset)], capsys)
    assert code == 0, err
    assert (seen["config"].expansions, seen["config"].nodes) == (300, None)


# ---------------------------------------------------------------- bad input: one line, nothing written


def _garbage_frames(directory: Path) -> None:
    (directory / FRAMES_FILE).write_bytes(b"this is not an npz archive")


def _nan_frame(directory: Path) -> None:
    path = directory / FRAMES_FILE
    with np.load(path) as archive:
        arrays = {name: archive[name] for name in archive.files}
    arrays["object_pos"][1, 0, 0, 0] = np.nan
    np.savez(path, **arrays)


@pytest.mark.parametrize(
    ("args", "prepare", "message"),
    [
        (["analyze", "{tmp}/missing", "--expansions", "5"], None, "does not exist"),
        (["evaluate", "{tmp}/missing"], None, "does not exist"),
        (["analyze", "{data}", "--expansions", "5", "--no-progress"], _garbage_frames, "is corrupt"),
        (["evaluate", "{data}"], _garbage_frames, "is corrupt"),
        (["analyze", "{data}", "--expansions", "5", "--no-progress"], _nan_frame, "object_pos [trajectory 1, frame 0"),
        (["evaluate", "{data}"], None, "run `energy-margin analyze` first"),
        (["analyze", "{data}", "--expansions", "-5"], None, "--expansions: expected an integer >= 0, got -5"),
        (["analyze", "{data}", "--nodes", "many"], None, "--nodes: expected an integer"),
        (["analyze", "{data}", "--workers", "0"], None, "--workers: expected an integer >= 1"),
        (["analyze", "{data}", "--lambda", "nan"], None, "--lambda: expected a finite number >= 0"),
        (["analyze", "{data}", "--cost", "heat"], None, "invalid choice"),
        (["analyze", "{data}", "--engine", "bullet", "--no-progress"], None, "invalid choice: 'bullet'"),
        (["analyze", "{data}", "--expansions", "0", "--no-progress"], None, "--expansions 0 grows no tree"),
        (["evaluate", "{scored}", "--capture-window", "3"], None, "--capture-window 3 needs more than 3 frames"),
        (["evaluate", "{scored}", "--success-frames", "4"], None, "--success-frames 4 exceeds the 3 frames"),
        (["evaluate", "{scored}", "--compare", "{scored}"], None, "compares the dataset with itself"),
        (["evaluate", "{data}", "--success-frames", "0"], None, "expected an integer >= 1"),
        ([*GENERATE[:2], "nope", *GENERATE[3:], "--out", "{tmp}/new"], None, "invalid choice: 'nope'"),
        (
            ["generate", "--task", "pushing", "--objects", "0", "--out", "{tmp}/new"],
            None,
            "--objects must be a positive integer, got 0",
        ),
        (
            ["generate", "--task", "pushing", "--objects", "1", "--trajectories", "0", "--out", "{tmp}/new"],
            None,
            "--trajectories must be a positive integer, got 0",
        ),
        (["generate", "--task", "pushing", "--objects", "1", "--out", "{tmp}/new", "--set", "bogus=1"], None, "bogus"),
        (
            ["generate", "--task", "pushing", "--objects", "1", "--out", "{tmp}/new", "--set", "wall_y"],
            None,
            "KEY=JSON",
        ),
        (["generate", "--task", "pushing", "--objects", "1", "--out", "{tmp}/new", "--set", "wall_y=[1"], None, "JSON"),
        (["generate", "--task", "pushing", "--objects", "two", "--out", "{tmp}/new"], None, "invalid int value"),
        (["generate", "--objects", "1", "--out", "{tmp}/new"], None, "--task"),
        ([*GENERATE, "--out", "{data}", "--seed", "5"], None, "already exists; pass --overwrite"),
        (["frobnicate"], None, "invalid choice"),
    ],
)
def test_bad_input_is_one_line_and_writes_nothing(
    tmp_path: Path,
    tiny_dataset: Path,
    capsys: pytest.CaptureFixture[str],
    args: list[str],
    prepare: Callable[[Path], None] | None,
    message: str,
) -> None:
    if prepare is not None:
        prepare(tiny_dataset)
    before = snapshot(tmp_path)
    if any("{scored}" in a for a in args):
        assert main(["analyze", str(tiny_dataset), "--expansions", "3", "--no-progress"]) == 0
        capsys.readouterr()
        before = snapshot(tmp_path)
    argv = [
        a.replace("{tmp}", str(tmp_path)).replace("{data}", str(tiny_dataset)).replace("{scored}", str(tiny_dataset))
        for a in args
    ]
    code, out, err = run_cli(argv, capsys)
    assert_one_error_line(code, err)
    assert message in err
    assert out == ""
    assert snapshot(tmp_path) == before


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (
            ["generate", "--task", "pushing", "--objects", "0", "--out", "{tmp}/new"],
            "--objects must be a positive integer, got 0",
        ),
        (
            ["generate", "--task", "pushing", "--objects", "1", "--frames", "0", "--out", "{tmp}/new"],
            "--frames must be a positive integer, got 0",
        ),
        (
            ["generate", "--task", "pushing", "--objects", "1", "--trajectories", "-2", "--out", "{tmp}/new"],
            "--trajectories must be a positive integer, got -2",
        ),
        (
            ["analyze", "{data}", "--converge", "1.5", "--no-progress"],
            "--converge must be a finite number > 0 and < 1, got 1.5",
        ),
        (
            ["analyze", "{data}", "--converge", "0", "--no-progress"],
            "--converge must be a finite number > 0 and < 1, got 0.0",
        ),
        (["control", "--period", "0", "--out", "{tmp}/run"], "--period must be a finite number > 0, got 0.0"),
        (["control", "--period", "nan", "--out", "{tmp}/run"], "--period must be a finite number > 0, got nan"),
        (["control", "--period", "-0.1", "--out", "{tmp}/run"], "--period must be a finite number > 0, got -0.1"),
    ],
)
def test_an_argument_the_library_refuses_is_named_by_its_flag(
    tmp_path: Path, tiny_dataset: Path, capsys: pytest.CaptureFixture[str], args: list[str], message: str
) -> None:
    # argparse takes these values; the library refuses them naming its keyword argument
    # (n_objects, converge, period), and the error line names the command's flag instead.
    before, data_before = snapshot(tmp_path), snapshot(tiny_dataset)
    argv = [a.replace("{tmp}", str(tmp_path)).replace("{data}", str(tiny_dataset)) for a in args]
    code, out, err = run_cli(argv, capsys)
    assert code == 2
    assert err.splitlines() == [f"energy-margin: error: {message}"]
    assert out == ""
    assert snapshot(tmp_path) == before and snapshot(tiny_dataset) == data_before


def test_a_parameter_without_a_flag_keeps_its_name(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    from energy_margin.errors import InvalidParameterError

    def refuse(name: str) -> Callable[..., None]:
        def generate_dataset(*args: object, **kwargs: object) -> None:
            raise InvalidParameterError(name, "must be a positive integer, got 0")

        return generate_dataset

    argv = ["generate", "--task", "pushing", "--objects", "1", "--out", str(tmp_path / "new")]
    # A name that is no keyword argument of the command is reported as the library wrote it.
    monkeypatch.setattr("energy_margin.data.generate.generate_dataset", refuse("count"))
    code, _, err = run_cli(argv, capsys)
    assert code == 2 and err.splitlines() == ["energy-margin: error: count must be a positive integer, got 0"]
    # A dest maps to its option; the command's table maps the names that differ.
    for name, flag in (("seed", "--seed"), ("engine", "--engine"), ("n_trajectories", "--trajectories")):
        monkeypatch.setattr("energy_margin.data.generate.generate_dataset", refuse(name))
        code, _, err = run_cli(argv, capsys)
        assert code == 2 and err.splitlines() == [f"energy-margin: error: {flag} must be a positive integer, got 0"]


def test_every_flag_table_names_options_of_its_command() -> None:
    from energy_margin.cli.app import COMMANDS, build_parser

    parser = build_parser()
    subparsers = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
    for command in COMMANDS:
        options = {o for a in subparsers.choices[command.NAME]._actions for o in a.option_strings}
        assert set(getattr(command, "PARAMETER_FLAGS", {}).values()) <= options, command.NAME
    analyze = subparsers.choices["analyze"].get_default("parameter_flags")
    assert analyze["likelihood_lambda"] == "--lambda" and analyze["workers"] == "--workers"
    assert "dataset" not in analyze and "help" not in analyze


def test_engine_errors_are_reported_on_one_line(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    argv = ["generate", "--task", "pushing", "--objects", "1", "--out", str(tmp_path / "new"), "--set", "object_mass=0"]
    code, _, err = run_cli(argv, capsys)
    assert list(tmp_path.iterdir()) == []
    assert_one_error_line(code, err)


def test_wrongly_typed_setting_is_a_user_error(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    argv = ["generate", "--task", "pushing", "--objects", "1", "--out", str(tmp_path / "new"), "--set", 'wall_y="abc"']
    code, _, err = run_cli(argv, capsys)
    assert list(tmp_path.iterdir()) == []
    assert_one_error_line(code, err, expected_code=2)


def test_damaged_archive_is_a_user_error(tiny_dataset: Path, capsys: pytest.CaptureFixture[str]) -> None:
    path = tiny_dataset / FRAMES_FILE
    data = bytearray(path.read_bytes())
    for i in range(200, 260):
        data[i] ^= 0xFF
    path.write_bytes(bytes(data))
    code, _, err = run_cli(["analyze", str(tiny_dataset), "--expansions", "5", "--no-progress"], capsys)
    assert_one_error_line(code, err, expected_code=2)
    assert "frames.npz" in err
    assert "corrupt" in err


def test_unexpected_errors_are_one_line_with_exit_1(
    tiny_dataset: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    def broken(*args: object, **kwargs: object) -> None:
        raise RuntimeError("boom")

    monkeypatch.setattr("energy_margin.evaluation.metrics.evaluate", broken)
    code, _, err = run_cli(["evaluate", str(tiny_dataset)], capsys)
    assert_one_error_line(code, err, expected_code=1)
    assert "RuntimeError: boom" in err
    assert "ENERGY_MARGIN_DEBUG=1" in err
    monkeypatch.setenv("ENERGY_MARGIN_DEBUG", "1")
    with pytest.raises(RuntimeError, match="boom"):
        main(["evaluate", str(tiny_dataset)])


def test_interrupt_exits_130(
    tiny_dataset: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    def interrupted(*args: object, **kwargs: object) -> None:
        raise KeyboardInterrupt

    monkeypatch.setattr("energy_margin.analysis.run.analyze_dataset", interrupted)
    code, _, err = run_cli(["analyze", str(tiny_dataset)], capsys)
    assert code == 130
    assert "run the same command again to resume" in err


# ---------------------------------------------------------------- as a separate process


@pytest.mark.slow
def test_module_entry_point_in_a_subprocess(tmp_path: Path) -> None:
    def cli(*args: str) -> subprocess.CompletedProcess[str]:
        return subprocess.run(
            [sys.executable, "-m", "energy_margin", *args], capture_output=True, text=True, timeout=120, check=False
        )

    data = tmp_path / "push"
    bad = cli("generate", "--task", "pushing", "--objects", "0", "--out", str(data))
    assert bad.returncode == 2
    assert bad.stderr.splitlines() == ["energy-margin: error: --objects must be a positive integer, got 0"]
    assert not data.exists()

    assert cli(*GENERATE[:4], "1", *GENERATE[5:], "--out", str(data)).returncode == 0
    analyzed = cli("analyze", str(data), "--expansions", "20", "--no-progress")
    assert analyzed.returncode == 0, analyzed.stderr
    evaluated = cli("evaluate", str(data), "--json")
    assert evaluated.returncode == 0, evaluated.stderr
    result = json.loads(evaluated.stdout)
    assert set(result) >= REQUIRED
    assert result["n_frames"] == 6


@pytest.mark.parametrize(
    ("command", "old", "value"),
    [
        ("analyze", "--iterations", ["7"]),
        ("calibrate", "--iterations", ["7"]),
        ("design", "--iterations", ["7"]),
        ("sweep", "--iterations", ["7"]),
        ("learn", "--iterations", ["7"]),
        ("budget", "--budgets", ["7", "9"]),
        ("study", "--budgets", ["7", "9"]),
        ("control", "--score-expansions", ["7"]),
    ],
)
def test_an_old_spelling_of_expansions_still_works_with_a_warning(
    command: str, old: str, value: list[str], capsys: pytest.CaptureFixture[str]
) -> None:
    from energy_margin.cli.app import build_parser

    parser = build_parser()
    subparsers = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
    sub = subparsers.choices[command]
    positional = [a for a in sub._actions if not a.option_strings and a.dest != "help"]
    required = [a for a in sub._actions if a.option_strings and a.required]
    argv = [command, *["x"] * len(positional)]
    for action in required:
        argv += [action.option_strings[0], str(next(iter(action.choices))) if action.choices else "1"]
    for group in sub._mutually_exclusive_groups:
        if group.required:
            argv += [group._group_actions[0].option_strings[0], "pushing"]
    new = parser.parse_args([*argv, "--expansions", *value])
    old_args = parser.parse_args([*argv, old, *value])
    assert old_args.expansions == new.expansions == ([int(v) for v in value] if len(value) > 1 else int(value[0]))
    assert f"{old} is now --expansions" in capsys.readouterr().err
    assert old not in sub.format_help()

"""A value the library refuses is reported as one line naming the command's flag (cli.app.flag_for)."""

from __future__ import annotations

from pathlib import Path

import pytest

from energy_margin.cli import main
from energy_margin.cli.app import error_message, flag_for
from energy_margin.errors import EnergyMarginError, InvalidParameterError


def run_cli(args: list[str], capsys: pytest.CaptureFixture[str]) -> tuple[int, str, str]:
    try:
        code = main(args)
    except SystemExit as exit_:
        code = exit_.code if isinstance(exit_.code, int) else 1
    captured = capsys.readouterr()
    return code, captured.out, captured.err


def test_flag_for_maps_a_parameter_to_the_option_of_its_command() -> None:
    assert flag_for("generate", "n_objects") == "--objects"
    assert flag_for("generate", "n_trajectories") == "--trajectories"
    assert flag_for("analyze", "likelihood_lambda") == "--lambda"
    assert flag_for("analyze", "capture_window") is None
    assert flag_for("evaluate", "capture_window") == "--capture-window"
    assert flag_for("record", "file_format") == "--format"
    assert flag_for("generate", "config") == "--set"


def test_error_message_names_flags_inside_the_message_too() -> None:
    flags = {"overwrite": "--overwrite", "out": "--out", "n_objects": "--objects", "policy": "--policy"}
    error = EnergyMarginError("d holds data; pass `overwrite=True` to replace them or choose another `out`")
    assert error_message(error, flags) == "d holds data; pass --overwrite to replace them or choose another --out"
    error = InvalidParameterError("model", "is only for `policy=learned`; `n_objects=3` differs, `seed` kept")
    assert error_message(error, flags) == "model is only for --policy learned; --objects 3 differs, `seed` kept"
    assert (
        error_message(error, {"model": "--model"})
        == "--model is only for `policy=learned`; `n_objects=3` differs, `seed` kept"
    )


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (
            ["analyze", "{data}", "--batch", "2", "--cost", "energy", "--no-progress"],
            "--cost must be 'wrench' with batch > 1, which does not integrate friction work, got 'energy'",
        ),
        (
            ["analyze", "{data}", "--contacts", "fast", "--engine", "pybullet", "--no-progress"],
            "--contacts 'fast' is a MuJoCo contact model, not available with engine 'pybullet'",
        ),
        (["analyze", "{data}", "--address", "auto", "--no-progress"], "--address is only for --executor ray"),
        (
            ["generate", "--task", "pushing", "--objects", "2", "--set", "bogus=1", "--out", "{tmp}/new"],
            "--set names unknown pushing configuration keys: bogus (task 'pushing')",
        ),
        (
            ["generate", "--task", "pushing", "--objects", "0", "--out", "{tmp}/new"],
            "--objects must be a positive integer, got 0",
        ),
        (
            [
                *["sweep", "--task", "pushing", "--param", "friction=0.3,0.5", "--trajectories", "2"],
                *["--out", "{tmp}/s", "--batch", "2", "--cost", "energy", "--no-progress"],
            ],
            "--cost must be 'wrench' with batch > 1, which does not integrate friction work, got 'energy'",
        ),
        (["evaluate", "{data}", "--capture-window", "99"], "--capture-window 99 needs more than 99 frames"),
        (
            ["perturb", "{data}", "--out", "{data}/copies", "--no-progress"],
            "--out {data}/copies must not be the dataset",
        ),
        (
            ["control", "--policy", "task", "--model", "m.npz", "--out", "{tmp}/c"],
            "--model is only for --policy learned",
        ),
    ],
)
def test_a_bad_value_is_one_line_naming_the_flag(
    tmp_path: Path, tiny_dataset: Path, capsys: pytest.CaptureFixture[str], args: list[str], message: str
) -> None:
    if args[0] == "evaluate":
        assert main(["analyze", str(tiny_dataset), "--expansions", "3", "--no-progress"]) == 0
        capsys.readouterr()
    argv = [a.replace("{tmp}", str(tmp_path)).replace("{data}", str(tiny_dataset)) for a in args]
    code, out, err = run_cli(argv, capsys)
    assert code == 2, err
    lines = err.splitlines()
    assert len(lines) == 1 and lines[0].startswith("energy-margin: error: "), err
    assert message.replace("{data}", str(tiny_dataset)) in lines[0]
    assert "Traceback" not in err and "`" not in lines[0]
    assert out == ""

"""The command registry: help texts, resume message, interrupts, file modes, optional engines."""

from __future__ import annotations

import os
import signal
import stat
import subprocess
import sys
import time
from pathlib import Path

import pytest

from energy_margin.cli import build_parser, main
from energy_margin.cli.app import COMMANDS

COMMAND_NAMES = (
    "scene",
    "generate",
    "record",
    "analyze",
    "evaluate",
    "calibrate",
    "monitor",
    "check",
    "perturb",
    "import-reference",
    "budget",
    "study",
    "sweep",
    "design",
    "learn",
    "control",
    "view",
    "render",
    "reproduce",
)


def test_every_command_is_registered_once() -> None:
    names = [command.NAME for command in COMMANDS]
    assert sorted(names) == sorted(COMMAND_NAMES)
    assert len(set(names)) == len(names)


@pytest.mark.parametrize("command", COMMANDS, ids=lambda c: c.NAME)
def test_each_command_has_a_summary_and_an_example(command: object, capsys: pytest.CaptureFixture[str]) -> None:
    summary, examples = command.SUMMARY, command.EXAMPLES  # type: ignore[attr-defined]
    assert summary and "\n" not in summary
    assert examples and all(line.startswith(f"energy-margin {command.NAME}") for line in examples)  # type: ignore[attr-defined]
    with pytest.raises(SystemExit) as exit_:
        main([command.NAME, "--help"])  # type: ignore[attr-defined]
    assert exit_.value.code == 0
    out = capsys.readouterr().out
    assert examples[0] in out
    assert summary[1:] in out


def test_top_level_help_lists_every_command_with_its_summary(capsys: pytest.CaptureFixture[str]) -> None:
    with pytest.raises(SystemExit):
        main(["--help"])
    out = " ".join(capsys.readouterr().out.split())
    for command in COMMANDS:
        assert command.NAME in out
        assert " ".join(command.SUMMARY.split()[:4]) in out


@pytest.mark.parametrize(
    ("command", "option", "choices"),
    [
        ("generate", "--task", ("pushing", "scooping")),
        ("generate", "--engine", ("mujoco", "pybullet")),
        ("analyze", "--engine", ("mujoco", "pybullet")),
        ("analyze", "--method", ("est", "montecarlo", "rrt")),
        ("analyze", "--cost", ("wrench", "energy")),
        ("reproduce", "--engine", ("mujoco", "pybullet")),
    ],
)
def test_choice_options_list_their_choices(
    command: str, option: str, choices: tuple[str, ...], capsys: pytest.CaptureFixture[str]
) -> None:
    with pytest.raises(SystemExit):
        main([command, "--help"])
    out = capsys.readouterr().out
    help_line = out[out.index(option) :]
    assert "{" + ",".join(choices) + "}" in help_line.split("\n")[0] or all(c in help_line[:400] for c in choices)


def test_an_added_command_touches_no_other_module(monkeypatch: pytest.MonkeyPatch) -> None:
    import types

    from energy_margin.cli import app

    hello = types.ModuleType("hello")
    hello.NAME, hello.SUMMARY, hello.EXAMPLES = "hello", "say hello", ("energy-margin hello",)
    hello.add_arguments = lambda parser: parser.add_argument("--name", default="world")
    hello.run = lambda args: print(f"hello {args.name}") or 0
    monkeypatch.setattr(app, "COMMANDS", (*app.COMMANDS, hello))
    assert app.main(["hello", "--name", "you"]) == 0


def test_resume_is_announced(tiny_dataset: Path, capsys: pytest.CaptureFixture[str]) -> None:
    from energy_margin.data.scores_file import JOURNAL_FILE, SCORES_FILE

    assert main(["analyze", str(tiny_dataset), "--expansions", "3"]) == 0
    journal = (tiny_dataset / JOURNAL_FILE).read_text().splitlines()
    (tiny_dataset / JOURNAL_FILE).write_text("\n".join(journal[:3]) + "\n")  # header + 2 rows
    (tiny_dataset / SCORES_FILE).unlink()
    capsys.readouterr()
    assert main(["analyze", str(tiny_dataset), "--expansions", "3"]) == 0
    assert "resuming: 2 of 6 frames already scored" in capsys.readouterr().err


def _modes(root: Path) -> dict[str, int]:
    return {str(path.relative_to(root)): stat.S_IMODE(path.stat().st_mode) for path in root.rglob("*")}


@pytest.mark.parametrize("umask", [0o022, 0o027])
def test_files_and_folders_follow_the_umask(tmp_path: Path, umask: int) -> None:
    script = (
        "import os, sys; os.umask(int(sys.argv[1], 8));"
        "from energy_margin.cli import main;"
        "d = sys.argv[2];"
        "assert main(['generate', '--task', 'pushing', '--objects', '1', '--trajectories', '1', '--frames', '2',"
        " '--out', d + '/data']) == 0;"
        "assert main(['analyze', d + '/data', '--expansions', '2', '--no-progress']) == 0"
    )
    subprocess.run([sys.executable, "-c", script, oct(umask)[2:], str(tmp_path)], check=True, capture_output=True)
    modes = _modes(tmp_path)
    assert modes["data"] == 0o777 & ~umask
    for name in ("dataset.json", "frames.npz", "scores.csv", "analysis.json", "scores.journal.csv"):
        assert modes[f"data/{name}"] == 0o666 & ~umask, name


@pytest.mark.parametrize("delay", [0.0, 0.3, 1.0], ids=["pool-starting", "early", "running"])
def test_interrupt_delivered_twice_is_one_line(tmp_path: Path, delay: float) -> None:
    data = tmp_path / "data"
    assert main(["generate", "--task", "pushing", "--objects", "3", "--trajectories", "2", "--frames", "3",
                 "--out", str(data)]) == 0  # fmt: skip
    command = [sys.executable, "-m", "energy_margin", "analyze", str(data), "--expansions", "20000", "--workers", "2"]
    process = subprocess.Popen(
        command, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, start_new_session=True
    )
    # Wait until the pool runs (the journal exists), then interrupt as `timeout -s INT` does: the
    # process itself, then its whole group (the main process receives SIGINT twice).
    deadline = time.monotonic() + 60
    while not (data / "scores.journal.csv").exists() and time.monotonic() < deadline:
        time.sleep(0.05)
    time.sleep(delay)
    process.send_signal(signal.SIGINT)
    os.killpg(process.pid, signal.SIGINT)
    _, err = process.communicate(timeout=60)
    lines = [line for line in err.replace("\r", "\n").splitlines() if line.strip() and not line.startswith("analyze")]
    assert process.returncode == 130, err
    assert lines == ["energy-margin: interrupted; run the same command again to resume"], err


def test_pybullet_without_the_extra_is_one_line(tiny_dataset: Path) -> None:
    # pybullet is installed for the tests: hide it, as on a machine without the extra.
    script = (
        "import sys; sys.modules['pybullet'] = None;"
        "from energy_margin.cli import main;"
        "sys.exit(main(['analyze', sys.argv[1], '--engine', 'pybullet', '--expansions', '2', '--no-progress']))"
    )
    result = subprocess.run([sys.executable, "-c", script, str(tiny_dataset)], capture_output=True, text=True)
    assert result.returncode == 2, result.stderr
    assert result.stderr.splitlines() == [
        "energy-margin: error: the pybullet engine needs the optional extra: pip install 'energy-margin[pybullet]'"
    ]


def test_build_parser_is_exported() -> None:
    assert build_parser().prog == "energy-margin"


def test_an_interrupt_inside_python_leaves_the_sigint_handler_alone(monkeypatch: pytest.MonkeyPatch) -> None:
    def interrupted(*args: object, **kwargs: object) -> None:
        raise KeyboardInterrupt

    monkeypatch.setattr("energy_margin.data.validation.require_valid", interrupted)
    before = signal.getsignal(signal.SIGINT)
    assert main(["analyze", "somewhere", "--no-progress"]) == 130
    # Child processes inherit an ignored SIGINT: main() called with arguments must not leave one.
    assert signal.getsignal(signal.SIGINT) is before

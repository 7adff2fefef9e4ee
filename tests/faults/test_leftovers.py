"""What a writer killed inside an atomic write leaves behind is removed by the next writer of the run."""

from __future__ import annotations

from pathlib import Path

import pytest

from energy_margin.cli import main
from energy_margin.data.scores_file import CONFIG_FILE, SCORES_FILE
from energy_margin.errors import EnergyMarginError
from energy_margin.runs import RunSpec, open_run
from energy_margin.runs.files import leftovers

SPEC = RunSpec(contents="tables", settings_file="run.json", outputs=("table.csv", "items"))


def test_a_first_settings_write_killed_midway_does_not_make_the_directory_foreign(tmp_path: Path) -> None:
    out = tmp_path / "run"
    out.mkdir()
    (out / ".run.json.k3x_9abc.tmp").write_text('{"se')  # killed inside the very first write
    with open_run(out, SPEC, {"seed": 1}) as run:
        assert not run.resumed
    assert sorted(p.name for p in out.iterdir()) == ["run.json"]


def test_leftovers_of_the_runs_own_files_go_and_nothing_else(tmp_path: Path) -> None:
    out = tmp_path / "run"
    with open_run(out, SPEC, {"seed": 1}):
        pass
    items = out / "items"
    items.mkdir()
    (items / "00000.npz").write_bytes(b"whole")
    stale = [
        out / ".run.json.abcdefgh.tmp",
        out / ".table.csv.0123abcd.tmp",
        out / ".table.csv.0123abce.csv",  # an atomic_path temporary
        items / ".00001.npz.zzzzzzzz.npz",
    ]
    for path in stale:
        path.write_text("torn")
    (items / ".staging.abcdefgh").mkdir()  # a staging folder inside the run's own folder
    with open_run(out, SPEC, {"seed": 1}) as run:
        assert run.resumed
    assert not any(path.exists() for path in stale)
    assert not (items / ".staging.abcdefgh").exists()
    assert (items / "00000.npz").read_bytes() == b"whole"
    assert leftovers(out) == [] and leftovers(items) == []
    # Anything else hidden is not the run's: a foreign file still makes the directory foreign.
    other = tmp_path / "other"
    other.mkdir()
    (other / ".notes.txt.abcdefgh.tmp").write_text("someone else's")
    with pytest.raises(EnergyMarginError, match="is not a directory of tables"):
        open_run(other, SPEC, {"seed": 1})
    assert (other / ".notes.txt.abcdefgh.tmp").exists()


def test_analyze_removes_what_a_killed_analyze_left_in_the_dataset(
    tiny_dataset: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    (tiny_dataset / f".{CONFIG_FILE}.abcdefgh.tmp").write_text("{")
    (tiny_dataset / f".{SCORES_FILE}.abcdefgh.tmp").write_text("trajectory,fr")
    (tiny_dataset / ".frames.npz.abcdefgh.npz").write_text("not the analysis's")  # the dataset's, not the run's
    assert main(["analyze", str(tiny_dataset), "--expansions", "5", "--no-progress"]) == 0
    capsys.readouterr()
    hidden = sorted(p.name for p in tiny_dataset.iterdir() if p.name.startswith("."))
    assert hidden == [".frames.npz.abcdefgh.npz"]


@pytest.mark.parametrize(
    ("argv", "temporary"),
    [
        (
            ["sweep", "--task", "pushing", "--param", "pusher_width=0.6", "--trajectories", "2", "--objects", "2"],
            "sweep.json",
        ),
        (
            ["control", "--episodes", "1", "--objects", "1", "--expansions", "0", "--set", "duration=0.1"],
            "control.json",
        ),
    ],
)
def test_a_command_killed_inside_its_first_settings_write_runs_again(
    argv: list[str], temporary: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "out"
    out.mkdir()
    (out / f".{temporary}.abcdefgh.tmp").write_text("{")
    extra = ["--expansions", "2", "--frames", "1", "--bootstrap", "5"] if argv[0] == "sweep" else ["--frames", "2"]
    code = main([*argv, *extra, "--out", str(out), "--no-progress"])
    assert code == 0, capsys.readouterr().err
    assert not [p for p in out.rglob(".*")]

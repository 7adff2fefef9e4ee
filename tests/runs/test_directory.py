"""One rule for resuming a run directory, and ``--overwrite``."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from energy_margin.errors import EnergyMarginError
from energy_margin.runs import RunLockedError, RunSpec, open_run, run_directory
from energy_margin.runs.directory import difference, run_versions
from energy_margin.runs.lock import LOCK_FILE

SPEC = RunSpec(contents="results", settings_file="run.json", outputs=("rows.csv", "items"), may_differ=("count",))


def test_settings_are_written_first_and_a_run_resumes(tmp_path: Path) -> None:
    out = tmp_path / "run"
    with run_directory(out, SPEC, {"seed": 0, "count": 2}) as run:
        assert not run.resumed and json.loads((out / "run.json").read_text()) == {
            "count": 2,
            "seed": 0,
            "versions": run_versions(),
        }
        assert (out / LOCK_FILE).exists()
        (out / "rows.csv").write_text("a\n")
    assert not (out / LOCK_FILE).exists()
    # A setting that may differ does not make another run; the new value is recorded.
    with run_directory(out, SPEC, {"seed": 0, "count": 5}) as run:
        assert run.resumed and (out / "rows.csv").exists()
        assert json.loads((out / "run.json").read_text())["count"] == 5


def test_other_settings_are_refused_then_replaced_with_overwrite(tmp_path: Path) -> None:
    out = tmp_path / "run"
    with run_directory(out, SPEC, {"seed": 0, "inner": {"a": 1}}):
        (out / "rows.csv").write_text("a\n")
        (out / "items").mkdir()
        (out / "notes.txt").write_text("the user's")
    with pytest.raises(EnergyMarginError) as caught:
        open_run(out, SPEC, {"seed": 0, "inner": {"a": 2}})
    assert str(caught.value) == (
        f"{out} holds results of other settings (inner.a: 1 there, 2 now); "
        "pass `overwrite=True` to replace them or choose another `out`"
    )
    assert (out / "rows.csv").exists() and not (out / LOCK_FILE).exists()  # nothing touched, lock released
    with run_directory(out, SPEC, {"seed": 0, "inner": {"a": 2}}, overwrite=True) as run:
        assert not run.resumed
        assert not (out / "rows.csv").exists() and not (out / "items").exists()
        assert (out / "notes.txt").read_text() == "the user's"  # never another file


def test_an_unreadable_settings_file_needs_overwrite(tmp_path: Path) -> None:
    (tmp_path / "run.json").write_text("{not json")
    with pytest.raises(EnergyMarginError, match="its settings file cannot be read"):
        open_run(tmp_path, SPEC, {"seed": 0})
    with run_directory(tmp_path, SPEC, {"seed": 0}, overwrite=True) as run:
        assert not run.resumed


def test_a_directory_of_other_files_is_refused_unless_shared(tmp_path: Path) -> None:
    (tmp_path / "dataset.json").write_text("{}")
    with pytest.raises(EnergyMarginError, match=r"already exists and is not a directory of results \(no run.json"):
        open_run(tmp_path, SPEC, {"seed": 0})
    shared = RunSpec(contents="scores", settings_file="run.json", shared_directory=True)
    with run_directory(tmp_path, shared, {"seed": 0}) as run:
        assert not run.resumed and (tmp_path / "dataset.json").exists()


def test_a_file_in_the_way_is_refused(tmp_path: Path) -> None:
    (tmp_path / "out").write_text("x")
    with pytest.raises(EnergyMarginError, match="exists and is not a directory"):
        open_run(tmp_path / "out", SPEC, {})


def test_a_second_writer_is_refused_and_nothing_is_written(tmp_path: Path) -> None:
    with run_directory(tmp_path, SPEC, {"seed": 0}):
        before = (tmp_path / "run.json").read_text()
        import subprocess
        import sys

        code = (
            "import sys\nfrom energy_margin.runs import RunSpec, open_run\n"
            "from energy_margin.errors import EnergyMarginError\n"
            "try:\n    open_run(sys.argv[1], RunSpec('results', 'run.json'), {'seed': 1}, overwrite=True)\n"
            "except EnergyMarginError as e:\n    print(e)\n"
        )
        out = subprocess.run([sys.executable, "-c", code, str(tmp_path)], capture_output=True, text=True, check=True)
        assert "is being written by process" in out.stdout
        assert (tmp_path / "run.json").read_text() == before
    assert issubclass(RunLockedError, EnergyMarginError)


def test_settings_under_a_key_keep_what_sits_beside_them(tmp_path: Path) -> None:
    spec = RunSpec(contents="episodes", settings_file="control.json", settings_key="settings", may_differ=("n",))
    with run_directory(tmp_path, spec, {"n": 1, "seed": 0}) as run:
        run.write_settings({"summary": {"rate": 0.5}})
    with run_directory(tmp_path, spec, {"n": 3, "seed": 0}) as run:
        assert run.resumed
    stored = json.loads((tmp_path / "control.json").read_text())
    assert stored == {"settings": {"n": 3, "seed": 0}, "summary": {"rate": 0.5}, "versions": run_versions()}


def test_a_resumed_run_keeps_what_it_decided_while_running(tmp_path: Path) -> None:
    spec = RunSpec(contents="scores", settings_file="run.json", compared=("seed",), kept=("choice",))
    with run_directory(tmp_path, spec, {"seed": 0}):
        stored = json.loads((tmp_path / "run.json").read_text())
        (tmp_path / "run.json").write_text(json.dumps({**stored, "choice": 16, "other": 1}))
    with run_directory(tmp_path, spec, {"seed": 0}) as run:
        assert run.resumed
    # The kept entry survives the resumed run's rewrite; what is not kept does not.
    assert json.loads((tmp_path / "run.json").read_text()) == {"seed": 0, "choice": 16, "versions": run_versions()}
    # Another run (overwritten) starts without it.
    with run_directory(tmp_path, spec, {"seed": 1}, overwrite=True):
        assert "choice" not in json.loads((tmp_path / "run.json").read_text())


def test_normalize_fills_settings_of_an_earlier_release() -> None:
    spec = RunSpec(
        contents="scores",
        settings_file="a.json",
        compared=("analyzer",),
        normalize=lambda settings, earlier: {
            **settings,
            "analyzer": {"rule": "window" if earlier else "new", **settings["analyzer"]},
        },
    )
    assert difference(spec, {"analyzer": {}}, {"analyzer": {"rule": "window"}}) is None
    assert difference(spec, {"analyzer": {}}, {"analyzer": {}}) == 'analyzer.rule: "window" there, "new" now'
    assert difference(spec, {"analyzer": {}, "versions": 1}, {"analyzer": {"rule": "window"}, "versions": 2}) is None

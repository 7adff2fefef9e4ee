import html
import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from energy_margin.errors import EnergyMarginError
from energy_margin.report.config import ReproduceConfig
from energy_margin.report.html import SECTIONS
from energy_margin.report.reproduce import ablation_markdown, reproduce, table_one_markdown

pytest.importorskip("matplotlib")

TINY = ReproduceConfig(
    quick=True,
    n_trajectories=3,
    n_frames=3,
    expansions=10,
    repeats=1,
    ablation_objects=(2, 3),
    ablation_n_trajectories=2,
    ablation_n_frames=3,
    workers=1,
)


@pytest.fixture(scope="module")
def reproduced(tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("reproduce")
    reproduce(out, TINY)
    return out


def _png_is_a_picture(path: Path) -> None:
    import matplotlib.image as mpimg

    assert path.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    image = mpimg.imread(path)
    assert image.ndim == 3 and image.shape[0] > 100 and image.shape[1] > 100
    rgb = image[..., :3].reshape(-1, 3)
    # A figure that shows data has many colours and is far from a blank canvas.
    assert len(np.unique(np.round(rgb, 2), axis=0)) > 20
    assert float(rgb.std()) > 0.05


@pytest.mark.slow
def test_report_has_every_section_and_real_figures(reproduced: Path) -> None:
    page = (reproduced / "report" / "index.html").read_text(encoding="utf-8")
    for key, title in SECTIONS:
        assert f'<section id="{key}">' in page
        assert title.split(":")[0] in page
    assert "<script" not in page
    sources = [part.split('"', 1)[0] for part in page.split('<img src="')[1:]]
    posters = [part.split('"', 1)[0] for part in page.split('poster="')[1:]]
    assert len(sources) >= 10 and len(posters) == 2
    for source in sources + posters:
        _png_is_a_picture(reproduced / "report" / source)
    figures = sorted((reproduced / "report" / "figures").glob("*.png"))
    assert {f.name for f in figures} == {Path(s).name for s in sources + posters}
    # Rendered frames of both tasks and perturbed states beside their true frames.
    assert sum("-render-" in s for s in sources) >= 6
    assert {"pushing-perturbed-true.png", "pushing-perturbed-perturbed.png", "pushing-perturbed-paper.png"} <= {
        Path(s).name for s in sources
    }
    assert "valid protocol" in page and "paper protocol" in page


@pytest.mark.slow
def test_report_embeds_one_video_per_task_and_links_the_views(reproduced: Path) -> None:
    import imageio.v3 as iio

    page = (reproduced / "report" / "index.html").read_text(encoding="utf-8")
    videos = [part.split('"', 1)[0] for part in page.split('<video src="')[1:]]
    assert sorted(videos) == ["videos/pushing.mp4", "videos/scooping.mp4"]
    # 2 s of pushing and 2.3 s of scooping at 30 pictures per second.
    counts = [iio.imread(reproduced / "report" / v, index=None, plugin="FFMPEG").shape[0] for v in sorted(videos)]
    assert counts == [61, 70]
    views = [part.split('"', 1)[0] for part in page.split('<a href="views/')[1:]]
    assert len(views) == 2
    for view in views:
        assert "Plotly.newPlot(" in (reproduced / "report" / "views" / view).read_text(encoding="utf-8")


@pytest.mark.slow
def test_report_states_its_provenance(reproduced: Path) -> None:
    import mujoco

    from energy_margin import __version__

    page = (reproduced / "report" / "index.html").read_text(encoding="utf-8")
    provenance = page[page.index('<section id="provenance">') : page.index("</section>")]
    for text in (f"energy-margin {__version__}", "git commit", f"mujoco {mujoco.__version__}", "core(s)"):
        assert text in provenance
    assert f"energy-margin reproduce --quick --out {reproduced}" in provenance
    stages = json.loads((reproduced / "stages.json").read_text(encoding="utf-8"))
    assert stages[0]["stage"] == "generate pushing-10" and stages[-1]["stage"] == "report"
    assert all(entry["seconds"] >= 0 for entry in stages)
    for entry in stages:
        assert html.escape(entry["stage"]) in provenance
    # A reproduced number away from the paper's gets its sentence.
    assert "Where the numbers differ from the paper's" in page and "docs/" in page


@pytest.mark.slow
def test_tables_hold_both_tasks_and_every_ablation_size(reproduced: Path) -> None:
    table = json.loads((reproduced / "table1.json").read_text(encoding="utf-8"))
    assert set(table) == {"pushing", "scooping"}
    for row in table.values():
        for key in ("capture_ap_perturbed", "success_ap_perturbed", "capture_score_error", "success_score_error"):
            assert set(row[key]) >= {"mean", "std"}
        # Table I under both protocols, the valid one also at the top level.
        assert set(row["by_protocol"]) == {"valid", "paper"}
        assert row["protocol"] == "valid"
        for protocol, entry in row["by_protocol"].items():
            assert entry["protocol"] == protocol and set(entry["capture_ap_perturbed"]) >= {"mean", "std"}
            suffix = "perturbed" if protocol == "valid" else "perturbed-paper"
            assert entry["perturbed"] == [f"data/{row['dataset'].split('/')[-1]}-{suffix}/1"]
            copy = json.loads((reproduced / entry["perturbed"][0] / "dataset.json").read_text(encoding="utf-8"))
            assert copy["perturbation"]["protocol"] == protocol
    ablation = json.loads((reproduced / "ablation.json").read_text(encoding="utf-8"))
    assert [row["n_objects"] for row in ablation] == [2, 3]
    assert all(row["runtime_per_frame_s"] > 0 for row in ablation)
    markdown = (reproduced / "table1.md").read_text(encoding="utf-8")
    assert "| paper |" in markdown and "0.79 ± 0.03" in markdown
    assert "this project, valid protocol" in markdown and "this project, paper protocol" in markdown
    assert "| 2 |" in (reproduced / "ablation.md").read_text(encoding="utf-8")


@pytest.mark.slow
def test_running_again_resumes_without_recomputing(
    reproduced: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    from energy_margin.report import html_figures, render

    scores = reproduced / "data" / "pushing-10" / "scores.csv"
    before = scores.read_bytes()
    # Without the render extra the report is still written, without videos and views.
    monkeypatch.setattr(html_figures, "_missing_render_extra", lambda: "plotly not installed")
    monkeypatch.setattr(render, "_warned", set())
    reproduce(reproduced, TINY)
    assert scores.read_bytes() == before
    # Nothing left to compute: no duration is announced.
    err = capsys.readouterr().err
    assert "every dataset is generated and analysed" in err and "expected about" not in err
    assert err.count("warning: the report leaves out videos and interactive views: plotly not installed") == 1
    page = (reproduced / "report" / "index.html").read_text(encoding="utf-8")
    assert "no interactive view (plotly not installed)" in page and "<video" not in page


@pytest.mark.slow
def test_other_settings_in_the_same_directory_are_refused(reproduced: Path) -> None:
    with pytest.raises(EnergyMarginError, match="other settings"):
        reproduce(reproduced, ReproduceConfig(quick=True, n_trajectories=4))


def test_markdown_tables_put_the_paper_beside_ours() -> None:
    row = {
        "n_objects": 10,
        "capture_ap": 0.99,
        "success_ap": 1.0,
        "capture_ap_perturbed": {"mean": 0.95, "std": 0.02},
        "success_ap_perturbed": {"mean": 0.97, "std": 0.01},
        "capture_score_error": {"mean": -0.01, "std": 0.2},
        "success_score_error": {"mean": 0.0, "std": 0.1},
    }
    text = table_one_markdown({"pushing": row})
    assert "| pushing | 10 | this project | 0.99 | 0.95 ± 0.02 |" in text
    assert "| | 10 | paper | 1.00 | 0.96 ± 0.01 |" in text
    # Both protocols, labelled, each with its own perturbed values; the paper's row last.
    paper_protocol = {**row, "capture_ap_perturbed": {"mean": 0.5, "std": 0.1}, "protocol": "paper"}
    both = {**row, "by_protocol": {"valid": {**row, "protocol": "valid"}, "paper": paper_protocol}}
    lines = table_one_markdown({"pushing": both}).splitlines()
    assert lines[2].startswith("| pushing | 10 | this project, valid protocol | 0.99 | 0.95 ± 0.02 |")
    assert lines[3].startswith("| | 10 | this project, paper protocol | 0.99 | 0.50 ± 0.10 |")
    assert lines[4].startswith("| | 10 | paper | 1.00 | 0.96 ± 0.01 |")
    ablation = ablation_markdown(
        [
            {
                "n_objects": 3,
                "capture_ap": 0.9,
                "success_ap": None,
                "runtime_per_frame_s": 0.1,
                "runtime_per_frame_std_s": 0.01,
            }
        ]
    )
    assert "| 3 | 0.90 | n/a | 0.100 ± 0.010 | 0.99 | 1.00 | 0.37 ± 0.13 |" in ablation


def test_expected_duration_comes_from_work_left_and_calibration(tmp_path: Path) -> None:
    from energy_margin.report.estimate import StepTimes, estimate_seconds, planned_analyses, work_left

    quick = ReproduceConfig.create(quick=True, workers=2, engine="mujoco", seed=0)
    plan = planned_analyses(quick, {"pushing": 10, "scooping": 5})
    # Each Table I set, its copies under both protocols, then the ablation.
    assert len(plan) == 2 * (1 + 2 * quick.repeats) + len(quick.ablation_objects)
    assert {e.protocol for e in plan if not e.generated} == {"valid", "paper"}
    frames, to_write = work_left(tmp_path, plan)
    assert sum(frames.values()) == sum(e.n_trajectories * e.n_frames for e in plan)
    assert len(to_write) == len(plan)
    calibration = StepTimes(
        {"pushing": 0.2, "scooping": 0.5},
        {"pushing": 0.1, "scooping": 0.3},
        {"pushing": 0.05, "scooping": 0.04},
        0.02,
        1,
    )
    seconds = estimate_seconds(calibration, frames, to_write, workers=1, report=False)

    def scale(entry):
        return entry.n_objects / (10 if entry.task == "pushing" else 5)

    expected = sum(count * (0.2 if e.task == "pushing" else 0.5) * scale(e) for e, count in frames.items())
    expected += sum(
        e.n_trajectories * (0.1 if e.task == "pushing" else 0.3) * scale(e)
        if e.generated
        else e.n_trajectories * e.n_frames * (0.05 if e.task == "pushing" else 0.04) * scale(e)
        for e in to_write
        # The paper protocol's draw checks nothing: its copies cost next to nothing to write.
        if e.generated or e.protocol != "paper"
    )
    assert seconds == pytest.approx(expected)
    # Twice the calibrated frame time: about twice as long.
    slower = StepTimes(
        {"pushing": 0.4, "scooping": 1.0},
        {"pushing": 0.1, "scooping": 0.3},
        {"pushing": 0.05, "scooping": 0.04},
        0.02,
        1,
    )
    assert estimate_seconds(slower, frames, to_write, workers=1, report=False) > 1.8 * seconds - 60


def test_calibration_measures_this_machine() -> None:
    from energy_margin.report.estimate import measure_step_times

    calibration = measure_step_times(ReproduceConfig(expansions=20, workers=1), ["pushing", "scooping"])
    assert set(calibration.frame_s) == set(calibration.perturb_s) == {"pushing", "scooping"}
    assert all(0 < value < 30 for value in calibration.frame_s.values())
    assert 0 < calibration.picture_s < 5 and calibration.measured_s < 60


@pytest.mark.slow
def test_reproduce_quick_runs_end_to_end(tmp_path: Path) -> None:
    out = tmp_path / "quick"
    completed = subprocess.run(
        [sys.executable, "-m", "energy_margin", "reproduce", "--quick", "--out", str(out), "--workers", "2"],
        capture_output=True,
        text=True,
        timeout=900,
        check=False,
    )
    assert completed.returncode == 0, completed.stderr[-2000:]
    assert "expected about" in completed.stderr and "on this machine (calibrated in" in completed.stderr
    assert (out / "report" / "index.html").is_file()
    table = json.loads((out / "table1.json").read_text(encoding="utf-8"))
    assert table["pushing"]["capture_ap"] is not None


def test_the_step_times_old_names_resolve_with_a_warning() -> None:
    from energy_margin.report import estimate

    with pytest.warns(DeprecationWarning, match="now measure_step_times"):
        assert estimate.calibrate is estimate.measure_step_times
    with pytest.warns(DeprecationWarning, match="now StepTimes"):
        assert estimate.Calibration is estimate.StepTimes

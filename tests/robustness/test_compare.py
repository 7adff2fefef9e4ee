from __future__ import annotations

import json
import shutil
from pathlib import Path

import numpy as np
import pytest

from energy_margin.cli import main
from energy_margin.data.dataset import load_dataset
from energy_margin.data.scores_file import SCORES_FILE
from energy_margin.errors import EnergyMarginError
from energy_margin.evaluation.metrics import evaluate
from energy_margin.robustness.compare import compare_perturbed, expand_compare_paths, format_robustness_table
from score_files import write_scores

# Hand-made labels for the 2 x 3 tiny dataset: mixed capture labels and mixed final success.
CAPTURED = np.array([[True, False, True], [True, True, False]])
IN_SUCCESS = np.array([[False, True, True], [False, False, False]])
TRUE_CAPTURE = np.array([[0.9, 0.1, 0.8], [0.7, 0.6, 0.2]])
TRUE_SUCCESS = np.array([[0.1, 0.5, 0.6], [0.2, 0.1, 0.1]])


@pytest.fixture
def table_one(tiny_dataset: Path, rewrite_frames, tmp_path: Path) -> tuple[Path, list[Path]]:  # type: ignore[no-untyped-def]
    """A scored true-state dataset and two scored 'perturbed' copies (hand-made scores)."""
    rewrite_frames(tiny_dataset, captured=CAPTURED, in_success=IN_SUCCESS)
    write_scores(tiny_dataset, TRUE_CAPTURE, TRUE_SUCCESS)
    parent = tmp_path / "perturbed"
    copies = []
    # Copy 1 ranks capture perfectly; copy 2 inverts it. Success scores shift by -0.1 and +0.3.
    for name, capture, shift in (("1", CAPTURED * 0.5 + 0.25, -0.1), ("2", 1.0 - CAPTURED * 0.9, 0.3)):
        target = parent / name
        shutil.copytree(tiny_dataset, target)
        write_scores(target, capture.astype(float), TRUE_SUCCESS + shift)
        copies.append(target)
    return tiny_dataset, copies


def test_table_one_keys_and_values(table_one: tuple[Path, list[Path]]) -> None:
    true, copies = table_one
    result = compare_perturbed(true, copies).to_dict()
    plain = evaluate(true)
    assert result["capture_ap"] == plain.capture_ap and result["success_ap"] == plain.success_ap
    aps = [evaluate(c).capture_ap for c in copies]
    assert aps[0] == 1.0
    assert result["capture_ap_perturbed"]["mean"] == pytest.approx(np.mean(aps))
    assert result["capture_ap_perturbed"]["std"] == pytest.approx(np.std(aps))
    assert result["capture_ap_perturbed"]["values"] == pytest.approx(aps)
    errors = np.stack([CAPTURED * 0.5 + 0.25 - TRUE_CAPTURE, 1.0 - CAPTURED * 0.9 - TRUE_CAPTURE])
    assert result["capture_score_error"]["mean"] == pytest.approx(errors.mean())
    assert result["capture_score_error"]["std"] == pytest.approx(errors.std())
    assert result["success_score_error"]["mean"] == pytest.approx(0.1)
    assert result["success_score_error"]["std"] == pytest.approx(0.2)
    for key in ("success_ap_perturbed", "capture_score_error", "success_score_error"):
        assert set(result[key]) >= {"mean", "std"}
    assert result["n_repeats"] == 2
    table = format_robustness_table(result)
    assert "capture" in table and "success" in table and "+0.10 ± 0.20" in table


def test_parent_directory_expands_in_numeric_order(table_one: tuple[Path, list[Path]]) -> None:
    true, copies = table_one
    parent = copies[0].parent
    shutil.copytree(copies[0], parent / "10")
    assert expand_compare_paths([parent]) == [parent / "1", parent / "2", parent / "10"]
    assert compare_perturbed(true, [parent]).n_repeats == 3


def test_cli_compare_json(table_one: tuple[Path, list[Path]], capsys: pytest.CaptureFixture[str]) -> None:
    true, copies = table_one
    assert main(["evaluate", str(true), "--compare", *map(str, copies), "--json"]) == 0
    result = json.loads(capsys.readouterr().out)
    for key in ("capture_ap", "success_ap"):
        assert isinstance(result[key], float)
    for key in ("capture_ap_perturbed", "success_ap_perturbed", "capture_score_error", "success_score_error"):
        assert isinstance(result[key]["mean"], float) and isinstance(result[key]["std"], float)
    assert main(["evaluate", str(true), "--compare", str(copies[0].parent)]) == 0
    assert "Table I" in capsys.readouterr().out


def test_mismatched_datasets_are_errors(
    table_one: tuple[Path, list[Path]], tmp_path: Path, capsys: pytest.CaptureFixture[str], rewrite_frames
) -> None:  # type: ignore[no-untyped-def]
    true, copies = table_one
    unscored = tmp_path / "unscored"
    shutil.copytree(copies[0], unscored)
    (unscored / SCORES_FILE).unlink()
    with pytest.raises(EnergyMarginError, match=r"scores\.csv"):
        compare_perturbed(true, [unscored])
    relabelled = tmp_path / "relabelled"
    shutil.copytree(copies[0], relabelled)
    rewrite_frames(relabelled, captured=~CAPTURED)
    with pytest.raises(EnergyMarginError, match="captured"):
        compare_perturbed(true, [relabelled])
    other = tmp_path / "other"
    shutil.copytree(copies[0], other)
    meta = json.loads((other / "dataset.json").read_text())
    meta["task"] = "scooping"
    (other / "dataset.json").write_text(json.dumps(meta))
    with pytest.raises(EnergyMarginError):
        compare_perturbed(true, [other])
    assert load_dataset(true) is not None
    # On the command line: one error line, non-zero exit.
    for bad in (unscored, relabelled, tmp_path / "missing", tmp_path):
        assert main(["evaluate", str(true), "--compare", str(bad)]) != 0
        err = capsys.readouterr().err.strip()
        assert err.count("\n") == 0 and "error" in err


def _mark_protocol(copy: Path, protocol: str | None) -> None:
    path = copy / "dataset.json"
    meta = json.loads(path.read_text())
    meta["perturbation"] = {"seed": 0} if protocol is None else {"seed": 0, "protocol": protocol}
    path.write_text(json.dumps(meta))


def test_the_copies_protocol_is_named_and_never_mixed(table_one: tuple[Path, list[Path]]) -> None:
    true, copies = table_one
    # Hand-made copies are not `perturb`'s: no protocol.
    assert compare_perturbed(true, copies).protocol is None
    for copy in copies:
        _mark_protocol(copy, "paper")
    result = compare_perturbed(true, copies).to_dict()
    assert result["protocol"] == "paper"
    assert "paper protocol" in format_robustness_table(result).splitlines()[0]
    # A copy written before protocols were recorded is a valid-protocol copy.
    _mark_protocol(copies[1], None)
    with pytest.raises(EnergyMarginError, match=r"mixes perturbation protocols.*is paper.*is valid"):
        compare_perturbed(true, copies)
    assert compare_perturbed(true, [copies[1]]).protocol == "valid"


def test_cli_compare_passes_the_verdicts_resamples_and_seed(
    table_one: tuple[Path, list[Path]], capsys: pytest.CaptureFixture[str]
) -> None:
    true, copies = table_one
    assert main(["evaluate", str(true), "--compare", *map(str, copies), "--json", "--resamples", "0"]) == 0
    assert "verdict" not in json.loads(capsys.readouterr().out)
    assert (
        main(["evaluate", str(true), "--compare", *map(str, copies), "--json", "--resamples", "7", "--seed", "3"]) == 0
    )
    result = json.loads(capsys.readouterr().out)
    assert (result["verdict_resamples"], result["seed"]) == (7, 3)

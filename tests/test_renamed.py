"""The names renamed for one concept, one name: the old ones keep working for one release, with a warning."""

from __future__ import annotations

import dataclasses
import json
from pathlib import Path

import numpy as np
import pytest

from energy_margin._renamed import renamed_keys, renamed_keyword
from energy_margin.analysis.frame import AnalyzerConfig, FrameScores
from energy_margin.data.scores_file import CONFIG_FILE, load_scores
from energy_margin.planning import TreeBudget
from energy_margin.report.config import ReproduceConfig


@pytest.mark.parametrize("cls", [AnalyzerConfig, TreeBudget, ReproduceConfig])
def test_the_old_keyword_and_attribute_iterations_give_expansions(cls: type) -> None:
    with pytest.warns(DeprecationWarning, match="'iterations' is now 'expansions'"):
        config = cls(iterations=7)
    assert config.expansions == 7
    with pytest.warns(DeprecationWarning, match=r"\.iterations is now .*\.expansions"):
        assert config.iterations == 7
    with pytest.warns(DeprecationWarning):
        changed = dataclasses.replace(config, iterations=9)
    assert changed.expansions == 9 and changed == cls(expansions=9)


def test_tree_budget_keeps_its_old_cap_name_too() -> None:
    with pytest.warns(DeprecationWarning, match="'max_iterations' is now 'max_expansions'"):
        budget = TreeBudget(expansions=None, nodes=3, max_iterations=50)
    assert budget.expansion_limit == 50


def test_frame_scores_read_by_the_old_name() -> None:
    scores = FrameScores(capture_score=1.0, success_score=0.0, nodes=3, expansions=2, runtime_s=0.1, physics_s=0.05)
    with pytest.warns(DeprecationWarning):
        assert scores.iterations == 2


def test_renamed_keyword_and_keys() -> None:
    @renamed_keyword(iterations="expansions")
    def grow(*, expansions: int) -> int:
        return expansions

    with pytest.warns(DeprecationWarning, match=r"grow\(\): 'iterations' is now 'expansions'"):
        assert grow(iterations=4) == 4
    with pytest.raises(TypeError, match="both"):
        grow(iterations=4, expansions=5)
    assert renamed_keys({"iterations": 3, "nodes": None}) == {"expansions": 3, "nodes": None}
    assert renamed_keys({"iterations": 3, "expansions": 5}) == {"expansions": 5}


def test_an_analysis_written_with_the_old_key_resumes_as_the_same_run(tiny_dataset: Path) -> None:
    from energy_margin.analysis.run import analyze

    config = AnalyzerConfig(expansions=5)
    analyze(tiny_dataset, config, seed=0, progress=False)
    before = load_scores(tiny_dataset)
    record = json.loads((tiny_dataset / CONFIG_FILE).read_text())
    record["analyzer"]["iterations"] = record["analyzer"].pop("expansions")
    (tiny_dataset / CONFIG_FILE).write_text(json.dumps(record))
    analyze(tiny_dataset, config, seed=0, progress=False)  # no "other settings" refusal
    np.testing.assert_array_equal(load_scores(tiny_dataset)["capture_score"], before["capture_score"])
    with pytest.raises(Exception, match="other settings"):
        analyze(tiny_dataset, AnalyzerConfig(expansions=6), seed=0, progress=False)

"""Fixtures of the analysis tests."""

from __future__ import annotations

from typing import Any

import pytest

from energy_margin.analysis.frame import FrameAnalyzer


@pytest.fixture
def count_frames(monkeypatch: pytest.MonkeyPatch) -> list[int]:
    """Record the index of every frame the analyzer computes (in this process)."""
    calls: list[int] = []
    original = FrameAnalyzer.__call__

    def counting(self: FrameAnalyzer, index: int) -> dict[str, Any]:
        calls.append(index)
        return original(self, index)

    monkeypatch.setattr(FrameAnalyzer, "__call__", counting)
    return calls

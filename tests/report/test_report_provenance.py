"""The report's provenance block records the engine versions of the one shared record."""

from __future__ import annotations

import mujoco
import numpy as np

from energy_margin.report.html import _provenance_html
from energy_margin.report.provenance import provenance
from energy_margin.runs.versions import engine_versions


def test_the_provenance_records_the_engine_and_its_versions() -> None:
    described = provenance(engine="mujoco", command="energy-margin reproduce", stages=[], total_s=1.0)
    assert described["engines"] == engine_versions("mujoco")
    assert described["engines"]["engine"] == "mujoco"
    assert "pybullet" in provenance(engine="pybullet", command="", stages=[], total_s=0.0)["engines"]


def test_the_report_names_the_engine_then_the_versions() -> None:
    described = provenance(engine="mujoco", command="energy-margin reproduce", stages=[], total_s=1.0)
    page = _provenance_html(described)
    assert f"mujoco (mujoco {mujoco.__version__}, numpy {np.__version__})" in page

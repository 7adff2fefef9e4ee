"""MuJoCo's warnings are read from the data and kept out of the working directory; the energy audit."""

from __future__ import annotations

from pathlib import Path

import mujoco
import pytest

from energy_margin import compat
from energy_margin.sim.mujoco_audit import (
    LOG_FILE,
    PHYSICS_WARNINGS,
    EnergyAudit,
    WarningLog,
    describe_warnings,
    raised_warnings,
    warning_numbers,
)

BALL = """
<mujoco>
  <option timestep="0.002" gravity="0 0 GRAVITY"/>
  <worldbody>
    <geom type="plane" size="2 2 0.1"/>
    <body name="ball" pos="0 0 0.5"><freejoint/><geom size="0.05" mass="0.2"/></body>
    <body name="arm" pos="0 0 1">
      <joint name="hinge" type="hinge" axis="0 1 0" damping="0.1"/>
      <geom type="capsule" fromto="0 0 0 0.3 0 0" size="0.02" mass="1"/>
    </body>
  </worldbody>
  <actuator><motor joint="hinge" gear="1"/></actuator>
</mujoco>
"""


def _model(gravity: str = "-9.81") -> tuple[mujoco.MjModel, mujoco.MjData]:
    model = mujoco.MjModel.from_xml_string(BALL.replace("GRAVITY", gravity))
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    return model, data


def _run(model: mujoco.MjModel, data: mujoco.MjData, audit: EnergyAudit, steps: int) -> None:
    for _ in range(steps):
        mujoco.mj_step(model, data)
        audit.after_step()


def test_a_sound_roll_out_gains_nothing_beyond_the_work_done_on_it() -> None:
    model, data = _model()
    audit = EnergyAudit(model, data)
    data.ctrl[0] = 2.0  # the motor works on the arm: its work is accounted for
    _run(model, data, audit, 500)
    assert audit.work > 0.1
    assert audit.gain() < 0.01
    assert raised_warnings(data) == {}


def test_energy_from_nothing_is_found() -> None:
    model, data = _model()
    audit = EnergyAudit(model, data)
    _run(model, data, audit, 50)
    data.qvel[:3] += 100.0  # no force did this
    assert audit.gain() > 0.2 * 0.5 * 3 * 100.0**2 * 0.9


def test_a_blow_up_is_read_from_the_warning_counters() -> None:
    model, data = _model("-1e200")
    with WarningLog():
        mujoco.mj_step(model, data, 3)
    raised = raised_warnings(data)
    assert raised.get("mjWARN_BADQACC", 0) >= 1
    assert warning_numbers(data).sum() == sum(raised.values())
    assert describe_warnings(raised).startswith("MuJoCo warned mjWARN_BADQACC")
    # Each count in its warning's place, and a copy: the counters go on without it.
    numbers = warning_numbers(data)
    assert dict(zip(PHYSICS_WARNINGS, numbers.tolist(), strict=True)) == {
        name: raised.get(name, 0) for name in PHYSICS_WARNINGS
    }
    data.warning[mujoco.mjtWarning.mjWARN_BADQACC].number += 1
    assert warning_numbers(data).sum() == numbers.sum() + 1


@pytest.mark.skipif(not compat.has_warning_hook(), reason="these MuJoCo bindings cannot take its warnings")
def test_mujoco_warnings_go_to_the_run_directory_not_the_working_one(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.chdir(tmp_path)
    model, data = _model("-1e200")
    with WarningLog() as log:
        mujoco.mj_step(model, data, 2)
    assert log.messages and "Nan, Inf or huge value" in log.messages[0]
    assert not (tmp_path / "MUJOCO_LOG.TXT").exists()
    run = tmp_path / "run"
    assert log.write(run) is None  # no directory, nothing written
    run.mkdir()
    assert log.write(run) == run / LOG_FILE
    assert (run / LOG_FILE).read_text(encoding="utf-8").splitlines() == log.messages
    # Leaving gives the warnings back to whoever had them before.
    with WarningLog() as outer:
        with WarningLog() as inner:
            mujoco.mj_resetData(model, data)
            mujoco.mj_step(model, data)
        mujoco.mj_resetData(model, data)
        mujoco.mj_step(model, data)
    assert len(inner.messages) == 1 and len(outer.messages) == 1

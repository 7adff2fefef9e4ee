"""What the fuzz tests of the readers share: deterministic settings, a tally of the cases, a scratch folder.

``ENERGY_MARGIN_FUZZ_TALLY=FILE`` makes each fuzz module append one JSON line to FILE at its end:
the reader, the cases generated, those accepted and those refused (every refusal one line).
"""

from __future__ import annotations

import json
import os
from collections import Counter
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from typing import Any

import pytest
from hypothesis import HealthCheck, settings

from energy_margin.errors import EnergyMarginError


def fuzz(examples: int) -> Callable[[Any], Any]:
    """Deterministic hypothesis settings with ``examples`` generated inputs."""
    return settings(
        max_examples=examples,
        deadline=None,
        derandomize=True,
        database=None,
        suppress_health_check=[HealthCheck.function_scoped_fixture, HealthCheck.too_slow, HealthCheck.data_too_large],
    )


class Tally(Counter[str]):
    """Cases, acceptances and refusals of one reader's fuzz module."""

    def __init__(self, reader: str) -> None:
        super().__init__()
        self.reader = reader

    def refused(self, error: EnergyMarginError) -> EnergyMarginError:
        """Count a refusal, after checking that its message is one non-empty line."""
        message = str(error)
        assert message and "\n" not in message and "\r" not in message, message
        self["refused"] += 1
        return error

    def report(self) -> None:
        """Append the tally to ``ENERGY_MARGIN_FUZZ_TALLY`` when it names a file."""
        target = os.environ.get("ENERGY_MARGIN_FUZZ_TALLY")
        if target:
            with open(target, "a", encoding="utf-8") as stream:
                stream.write(json.dumps({"reader": self.reader, **self}) + "\n")


def damaged(content: bytes, edit: str, position: float, value: int, *, width: int) -> bytes:
    """``content`` cut at ``position`` (a fraction of its length), a byte there set, or ``width`` bytes overwritten."""
    damaged = bytearray(content)
    index = int(position * len(damaged))
    if edit == "truncate":
        damaged = damaged[:index]
    elif edit == "byte":
        damaged[index] = value if damaged[index] != value else value ^ 0xFF
    else:
        damaged[index : index + width] = bytes([value]) * len(damaged[index : index + width])
    return bytes(damaged)


@contextmanager
def scratch_folder(tmp_path_factory: pytest.TempPathFactory) -> Iterator[None]:
    """Work in a fresh folder: MuJoCo writes the warnings of a damaged model to MUJOCO_LOG.TXT there."""
    with pytest.MonkeyPatch.context() as patch:
        patch.chdir(tmp_path_factory.mktemp("mujoco-log"))
        yield

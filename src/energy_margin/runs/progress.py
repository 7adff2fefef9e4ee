"""The one progress bar of every long command: tqdm on standard error, a callback, or nothing.

Every function of the package that runs long takes ``progress`` (:data:`Progress`): ``True``
draws a bar on standard error, a callable receives the number of items each step finished
(``progress(1)`` after a trajectory, a frame, an episode), ``False`` or ``None`` shows nothing.
"""

from __future__ import annotations

import contextlib
import sys
from collections.abc import Callable
from typing import Any, TypeAlias

__all__ = [
    "Progress",
    "close_all",
    "progress_bar",
]

#: What a long function does as items finish: ``True`` a bar on standard error, a callable is
#: called with the number of items finished, ``False`` or ``None`` nothing.
Progress: TypeAlias = bool | Callable[[int], None] | None


class _CallbackBar:
    def __init__(self, callback: Callable[[int], None]) -> None:
        self.callback = callback

    def update(self, count: int = 1) -> None:
        self.callback(count)

    def set_postfix_str(self, text: str) -> None:
        del text

    def close(self) -> None:
        pass


class _NoBar:
    def update(self, count: int = 1) -> None:
        del count

    def set_postfix_str(self, text: str) -> None:
        del text

    def close(self) -> None:
        pass


def progress_bar(total: int, *, desc: str, initial: int = 0, enabled: Progress, unit: str = "frame") -> Any:
    """A tqdm bar on standard error (``update``, ``set_postfix_str``, ``close``), a callback, or nothing.

    Args:
        total: number of items of the whole run.
        desc: the label before the bar (the command's name).
        initial: items already done (a resumed run).
        enabled: the caller's ``progress`` (:data:`Progress`): ``True`` a tqdm bar, a callable
            gets each ``update``'s count, ``False`` or ``None`` a bar that prints nothing.
        unit: what one item is ("frame", "episode", "copy").

    """
    if callable(enabled):
        return _CallbackBar(enabled)
    if not enabled:
        return _NoBar()
    from tqdm import tqdm

    return tqdm(total=total, initial=initial, unit=unit, desc=desc, dynamic_ncols=True)


def close_all() -> None:
    """Close every progress bar still open (an interrupt or an error arrived while one was drawn).

    A command's last line (an error, "interrupted") then starts on a line of its own, even when
    the interrupt landed while a bar was being created, before any ``finally`` could close it.
    """
    tqdm_module = sys.modules.get("tqdm")
    if tqdm_module is None:
        return
    for bar in list(getattr(tqdm_module.tqdm, "_instances", ())):
        if not hasattr(bar, "disable"):
            # Interrupted inside tqdm's own constructor (while it started its monitor thread): the
            # bar is registered but half built, and its close() (also run when it is collected)
            # would raise. Nothing was drawn: mark it closed and forget it.
            bar.disable = True
            with contextlib.suppress(KeyError, TypeError):
                tqdm_module.tqdm._instances.remove(bar)
            continue
        bar.close()

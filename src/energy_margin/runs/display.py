"""Figures as display objects built from a result, drawn only when asked (matplotlib loads then).

As scikit-learn's ``*Display`` classes do, a display holds what a figure shows, is built from a
result by a ``from_result`` class method of its subclass, and draws with :meth:`Display.plot`;
the computation itself never plots. :meth:`Display.save` writes the figure, or returns ``None``
when matplotlib (the ``plot`` extra) is not installed.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

from energy_margin.runs.files import atomic_path

__all__ = [
    "Display",
    "pyplot",
]


def pyplot() -> Any | None:
    """The pyplot module of matplotlib on the Agg backend, or ``None`` without matplotlib."""
    try:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError:
        return None
    return plt


class Display:
    """Base class of the figures; a subclass implements :meth:`draw`.

    Attributes:
        figure_: the matplotlib figure of the last :meth:`plot`, ``None`` before.

    """

    figure_: Any = None

    def draw(self, plt: Any) -> Any:
        """Draw the figure with pyplot ``plt`` and return it."""
        raise NotImplementedError

    def plot(self) -> Display:
        """Draw the figure (``figure_``); raises ``ImportError`` without matplotlib."""
        plt = pyplot()
        if plt is None:
            raise ImportError("drawing a figure needs matplotlib: pip install 'energy-margin[plot]'")
        self.figure_ = self.draw(plt)
        return self

    def save(self, path: Path | str, *, dpi: int = 120) -> Path | None:
        """Draw and write the figure to ``path`` (atomically); ``None`` without matplotlib."""
        plt = pyplot()
        if plt is None:
            return None
        figure = self.draw(plt)
        path = Path(path)
        try:
            with atomic_path(path) as temporary:
                figure.savefig(temporary, dpi=dpi, format=path.suffix.lstrip(".") or "png")
        finally:
            plt.close(figure)
        return path

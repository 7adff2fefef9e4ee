"""The HTML building blocks of the report: formatted numbers, tables, figures, image grids."""

from __future__ import annotations

import html
from typing import Any

__all__ = []


def _fmt(value: Any) -> str:
    if value is None:
        return "n/a"
    if isinstance(value, dict):
        return "n/a" if value.get("mean") is None else f"{value['mean']:.2f} ± {value['std']:.2f}"
    if isinstance(value, tuple | list):
        return f"{value[0]:.2f} ± {value[1]:.2f}"
    return f"{value:.2f}" if isinstance(value, float) else html.escape(str(value))


def _table(header: list[str], rows: list[list[Any]]) -> str:
    head = "".join(f"<th>{html.escape(cell)}</th>" for cell in header)
    body = "".join("<tr>" + "".join(f"<td>{_fmt(cell)}</td>" for cell in row) + "</tr>" for row in rows)
    return f"<table><thead><tr>{head}</tr></thead><tbody>{body}</tbody></table>"


def _figure(name: str, caption: str) -> str:
    return (
        f'<figure><img src="figures/{name}" alt="{html.escape(caption)}">'
        f"<figcaption>{html.escape(caption)}</figcaption></figure>"
    )


def _image(source: str, caption: str) -> str:
    return (
        f'<figure class="cell"><img src="{html.escape(source)}" alt="{html.escape(caption)}">'
        f"<figcaption>{html.escape(caption)}</figcaption></figure>"
    )


def _grid(cells: list[str]) -> str:
    return f'<div class="grid">{"".join(cells)}</div>'

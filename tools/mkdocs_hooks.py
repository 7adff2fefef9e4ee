"""Hooks of the docs site (``mkdocs.yml``).

* ``docs/reference/cli.md`` holds a marker that is replaced, at every build, by the reference that
  :mod:`cli_reference` generates from the ``energy-margin`` argument parsers.
* ``docs/reference/architecture.md`` holds another, replaced by every module of the package with
  the first line of its docstring (:mod:`module_index`).
* A page's relative link to a repository file outside ``docs/`` (an example's README) becomes a
  link into the repository at ``repo_url`` when the site has one, else the file's path as code.
  ``tests/test_docs.py`` checks that every such file exists.
"""

from __future__ import annotations

import posixpath
import re
import sys
from pathlib import Path
from typing import Any

sys.path.insert(0, str(Path(__file__).resolve().parent))

import cli_reference
import module_index

_LINK = re.compile(r"\[([^\]]+)\]\(((?:\.\./)+[^)#\s]+)(#[^)\s]*)?\)")


def _outside_links(markdown: str, page_path: str, repo_url: str | None) -> str:
    def replace(match: re.Match[str]) -> str:
        text, target, anchor = match.group(1), match.group(2), match.group(3) or ""
        resolved = posixpath.normpath(posixpath.join("docs", posixpath.dirname(page_path), target))
        if resolved.startswith("docs/"):
            return match.group(0)
        if repo_url:
            return f"[{text}]({repo_url.rstrip('/')}/blob/main/{resolved}{anchor})"
        return f"{text} (`{resolved}`)"

    return _LINK.sub(replace, markdown)


def on_page_markdown(markdown: str, page: Any, config: Any, **_: Any) -> str:
    """Insert the generated references; turn links out of ``docs/`` into repository links."""
    if cli_reference.MARKER in markdown:
        markdown = markdown.replace(cli_reference.MARKER, cli_reference.markdown())
    if module_index.MARKER in markdown:
        markdown = markdown.replace(module_index.MARKER, module_index.markdown())
    return _outside_links(markdown, page.file.src_uri, config.get("repo_url"))

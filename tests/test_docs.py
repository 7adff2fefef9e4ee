"""The docs site cannot go stale: cited pages exist, every page is in the nav, links resolve."""

import re
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
DOCS = ROOT / "docs"
#: Where the project cites documentation pages by path.
CITING = ["src", "tests", "examples", "benchmarks", "tools", ".ci", "README.md", "CHANGELOG.md", "noxfile.py"]
CITED = re.compile(r"(?<![\w-])docs/[\w./-]*?\.md\b")
SUFFIXES = {".py", ".md", ".toml", ".sh", ".txt", ""}
LINK = re.compile(r"\]\(([^)\s#]+)(?:#[^)\s]*)?\)")


def citing_files() -> list[Path]:
    files: list[Path] = []
    for name in CITING:
        path = ROOT / name
        if path.is_file():
            files.append(path)
        elif path.is_dir():
            files += [p for p in path.rglob("*") if p.is_file() and p.suffix in SUFFIXES]
    # Build outputs (an egg-info's copy of an older README, caches) are not the project's text.
    return [
        path for path in files if not any(part == "__pycache__" or part.endswith(".egg-info") for part in path.parts)
    ]


def test_every_cited_docs_page_exists() -> None:
    missing = []
    for path in citing_files():
        text = path.read_text(encoding="utf-8", errors="replace")
        for match in CITED.finditer(text):
            if not (ROOT / match.group(0)).is_file():
                missing.append(f"{path.relative_to(ROOT)}: {match.group(0)}")
    assert not missing, "cited docs pages that do not exist:\n" + "\n".join(missing)


def nav_pages() -> set[str]:
    text = (ROOT / "mkdocs.yml").read_text(encoding="utf-8")
    nav = text.split("\nnav:", 1)[1]
    return set(re.findall(r"([\w./-]+\.md)\s*$", nav, flags=re.M))


def test_every_page_is_in_the_nav_and_every_nav_entry_exists() -> None:
    pages = {path.relative_to(DOCS).as_posix() for path in DOCS.rglob("*.md")}
    nav = nav_pages()
    assert pages - nav == set(), "pages missing from mkdocs.yml's nav"
    assert nav - pages == set(), "nav entries without a page"


@pytest.mark.parametrize("page", sorted(p.relative_to(ROOT).as_posix() for p in DOCS.rglob("*.md")))
def test_relative_links_resolve(page: str) -> None:
    path = ROOT / page
    broken = []
    for target in LINK.findall(path.read_text(encoding="utf-8")):
        if re.match(r"^[a-z]+:", target) or target.startswith("/"):
            continue
        if not (path.parent / target).exists():
            broken.append(target)
    assert not broken, f"{page}: links to missing files: {broken}"


def test_readme_links_resolve() -> None:
    text = (ROOT / "README.md").read_text(encoding="utf-8")
    broken = [t for t in LINK.findall(text) if not re.match(r"^[a-z]+:", t) and not (ROOT / t).exists()]
    assert not broken


def test_cli_reference_lists_every_command() -> None:
    sys.path.insert(0, str(ROOT / "tools"))
    try:
        import cli_reference
    finally:
        sys.path.remove(str(ROOT / "tools"))
    from energy_margin.cli.app import COMMANDS

    text = cli_reference.markdown()
    for command in COMMANDS:
        assert f"\n## {command.NAME}\n" in text
    assert cli_reference.MARKER in (DOCS / "reference" / "cli.md").read_text(encoding="utf-8")


def test_architecture_lists_every_module() -> None:
    sys.path.insert(0, str(ROOT / "tools"))
    try:
        import module_index
    finally:
        sys.path.remove(str(ROOT / "tools"))
    text = module_index.markdown()
    for path in (ROOT / "src" / "energy_margin").rglob("*.py"):
        parts = path.relative_to(ROOT / "src").with_suffix("").parts
        name = ".".join(parts[:-1] if parts[-1] == "__init__" else parts)
        assert f"| `{name}` |" in text
    assert module_index.MARKER in (DOCS / "reference" / "architecture.md").read_text(encoding="utf-8")

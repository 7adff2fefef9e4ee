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


#: A relative link with an anchor: ``[text](page.md#anchor)`` or ``[text](#anchor)``.
ANCHORED = re.compile(r"\]\(([^)\s#]*)#([^)\s]+)\)")
FENCE = re.compile(r"^(```|~~~).*?^\1", re.S | re.M)
#: Pages whose headings are generated when the site builds (the API and CLI references).
GENERATED = ("docs/reference/api/", "docs/reference/cli.md")


def heading_anchor(heading: str) -> str:
    """The anchor the site gives a heading (mkdocs.yml: pymdownx's GitHub slug, lower case)."""
    text = re.sub(r"\[([^\]]*)\]\([^)]*\)", r"\1", heading)  # a link keeps its text
    text = re.sub(r"<[^>]+>", "", text).replace("`", "")
    return re.sub(r"[^\w\- ]", "", text.strip().lower()).replace(" ", "-")


def page_anchors(page: Path) -> set[str]:
    """Every anchor of a page: its headings' (a repeated one gets ``_1``, ``_2``) and explicit ones."""
    found: set[str] = set()
    seen: dict[str, int] = {}
    for line in FENCE.sub("", page.read_text(encoding="utf-8")).splitlines():
        heading = re.match(r"^#{1,6}\s+(.*?)\s*#*\s*$", line)
        if heading:
            explicit = re.search(r"\{#([^}]+)\}\s*$", heading.group(1))
            base = explicit.group(1) if explicit else heading_anchor(heading.group(1))
            count = seen.get(base, 0)
            seen[base] = count + 1
            found.add(base if count == 0 else f"{base}_{count}")
        for pair in re.findall(r'\{#([\w-]+)\}|<a (?:id|name)="([\w-]+)"', line):
            found.update(name for name in pair if name)
    return found


def test_heading_anchors_are_spelled_as_the_site_spells_them() -> None:
    assert heading_anchor("Success beyond a tree's reach (`--continuation`)") == (
        "success-beyond-a-trees-reach---continuation"
    )
    assert heading_anchor("Pushing, n_o = 10, 20 trajectories × 10 frames") == (
        "pushing-n_o--10-20-trajectories--10-frames"
    )


@pytest.mark.parametrize("page", [*sorted(p.relative_to(ROOT).as_posix() for p in DOCS.rglob("*.md")), "README.md"])
def test_anchored_links_land_on_a_heading(page: str) -> None:
    path = ROOT / page
    broken = []
    for target, anchor in ANCHORED.findall(FENCE.sub("", path.read_text(encoding="utf-8"))):
        destination = (path.parent / target).resolve() if target else path
        relative = destination.relative_to(ROOT).as_posix() if destination.is_relative_to(ROOT) else ""
        if re.match(r"^[a-z]+:", target) or destination.suffix != ".md" or not destination.is_file():
            continue
        if relative.startswith(GENERATED):
            continue
        if anchor not in page_anchors(destination):
            broken.append(f"{target}#{anchor}")
    assert not broken, f"{page}: links to anchors no heading has: {broken}"

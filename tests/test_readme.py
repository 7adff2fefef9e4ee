import re
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def quick_start_commands() -> list[str]:
    text = (ROOT / "README.md").read_text(encoding="utf-8")
    section = text.split("## Quick start", 1)[1].split("\n## ", 1)[0]
    return [block.strip() for block in re.findall(r"```bash\n(.*?)```", section, flags=re.S)]


def test_quick_start_has_exactly_two_commands() -> None:
    commands = quick_start_commands()
    assert len(commands) == 2
    assert all("\n" not in command for command in commands)
    assert "energy-margin" in commands[0]
    assert "pytest" in commands[1]


def test_ci_runs_the_readme_test_command() -> None:
    ci_script = (ROOT / ".ci" / "run").read_text(encoding="utf-8")
    assert quick_start_commands()[1] in ci_script.splitlines()


def python_example() -> str:
    text = (ROOT / "README.md").read_text(encoding="utf-8")
    section = text.split("Python, one frame", 1)[1]
    return re.findall(r"```python\n(.*?)```", section, flags=re.S)[0]


def test_python_example_runs_on_a_small_dataset(tiny_dataset: Path, monkeypatch, capsys) -> None:  # type: ignore[no-untyped-def]
    import sys

    monkeypatch.setattr(sys, "argv", ["example", str(tiny_dataset)])
    source = python_example().replace("expansions=300", "expansions=5")
    exec(compile(source, "README.md", "exec"), {"__name__": "__main__"})
    capture, success, _ = capsys.readouterr().out.split(maxsplit=2)
    assert 0.0 <= float(capture) <= 1.0
    assert 0.0 <= float(success) <= 1.0

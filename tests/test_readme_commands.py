"""The README's two commands are the ones CI runs: the test command is `.ci/run`'s last
line word for word, and the install script both name is the one that exists."""

from __future__ import annotations

import re
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def readme_commands() -> list[str]:
    """The first two ```bash blocks of the README, each one line."""
    text = (ROOT / "README.md").read_text(encoding="utf-8")
    blocks = re.findall(r"```bash\n(.*?)```", text, flags=re.S)
    return [b.strip() for b in blocks[:2]]


def test_the_readme_starts_with_the_demo_and_the_test_command() -> None:
    demo, tests = readme_commands()
    assert "\n" not in demo and "\n" not in tests
    assert demo.endswith("reachwise demo")
    assert tests.endswith("pytest")


def test_ci_runs_the_readmes_test_command_exactly() -> None:
    _, tests = readme_commands()
    lines = [
        line.strip()
        for line in (ROOT / ".ci" / "run").read_text(encoding="utf-8").splitlines()
        if line.strip() and not line.lstrip().startswith(("#", "set ", "cd "))
    ]
    assert lines[-1] == tests


def test_the_install_script_the_command_names_exists_and_installs_the_browser() -> None:
    _, tests = readme_commands()
    script = re.match(r"bash (\S+) &&", tests)
    assert script is not None
    path = ROOT / script.group(1)
    body = path.read_text(encoding="utf-8")
    assert "chromium" in body and '-e ".[dev]"' in body

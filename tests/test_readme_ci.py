"""The README says what CI runs: its test command, verbatim up to the quiet install, and every setting .ci/run
adds before it is named in the README."""
from __future__ import annotations

import re
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def _readme_test_command() -> str:
    text = (ROOT / "README.md").read_text()
    match = re.search(r"Install and run the tests:\s*```bash\n(.+?)\n```", text, re.S)
    assert match, "README: the 'Install and run the tests' block is missing"
    return match.group(1).strip()


def test_ci_runs_the_readme_test_command():
    command = _readme_test_command()
    assert "pytest" in command
    ci = (ROOT / ".ci" / "run").read_text().splitlines()
    quiet = command.replace("pip install -e", "pip install -q -e")
    assert any(line.strip() in (command, quiet) for line in ci), f".ci/run does not run {command!r}"


def test_readme_names_what_ci_adds():
    readme = (ROOT / "README.md").read_text()
    ci = (ROOT / ".ci" / "run").read_text()
    command = _readme_test_command()
    head = ci[:ci.index(command.split(" && ")[0])]   # what .ci/run does before the test command
    for var in re.findall(r"^export (\w+)=(\S+)", head, re.M):
        assert f"{var[0]}={var[1]}" in readme, f"README does not say that CI sets {var[0]}={var[1]}"
    if re.search(r"^rm -rf \.venv", head, re.M):
        assert "removes any `.venv`" in readme
    if "pip install -q" in ci and "pip install -q" not in command:
        assert "`pip install -q`" in readme

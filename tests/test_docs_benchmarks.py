"""docs/accuracy.md lists every benchmark script with its command and its results file, and the files it links
exist (the README sends readers there for the full tables)."""
from __future__ import annotations

import re
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def test_every_benchmark_is_listed_with_a_results_file_that_exists():
    text = (ROOT / "docs" / "accuracy.md").read_text()
    scripts = sorted(p.stem for p in (ROOT / "benchmarks").glob("*.py"))
    assert scripts
    for name in scripts:
        assert f"`python benchmarks/{name}.py" in text, f"docs/accuracy.md does not list benchmarks/{name}.py"
    for link in re.findall(r"\]\((\.\./benchmarks/results/[^)]+)\)", text):
        assert (ROOT / "docs" / link).resolve().is_file(), f"docs/accuracy.md links a missing file: {link}"

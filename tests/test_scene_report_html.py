"""The scene's HTML report: one self-contained page (nothing fetched), the cycle table with the run's numbers,
every figure of the run embedded byte for byte, the settings and the timings. (A real browser opens it in
tests/browser/check_report.py, run by .ci/run.)"""
import base64
import re
from html.parser import HTMLParser

import matplotlib

matplotlib.use("Agg")
import pytest  # noqa: E402

from dfloop.scene import load_scene, run_scene  # noqa: E402

SCENE = """
[scene]
name = "servo_html"
title = "Servo 5/(s(s+1)) with backlash h = 1 <check & escape>"

[plant]
num = [5.0]
den = [1.0, 1.0, 0.0]

[element]
type = "Backlash"
h = 1.0

[analysis]
exact = true
verify = true
plots = ["nyquist"]
"""


class _Page(HTMLParser):
    """Tags with their attributes, and the text of every table cell by table id."""

    def __init__(self):
        super().__init__()
        self.tags, self.cells, self.table, self.row, self.cell = [], {}, None, None, None

    def handle_starttag(self, tag, attrs):
        attrs = dict(attrs)
        self.tags.append((tag, attrs))
        if tag == "table":
            self.table = attrs.get("id")
            self.cells[self.table] = []
        elif tag == "tr" and self.table is not None:
            self.row = []
            self.cells[self.table].append(self.row)
        elif tag in ("td", "th") and self.row is not None:
            self.cell = []

    def handle_endtag(self, tag):
        if tag in ("td", "th") and self.cell is not None:
            self.row.append("".join(self.cell).strip())
            self.cell = None
        elif tag == "table":
            self.table = None

    def handle_data(self, data):
        if self.cell is not None:
            self.cell.append(data)


@pytest.fixture(scope="module")
def run(tmp_path_factory):
    out = tmp_path_factory.mktemp("html")
    path = out / "servo_html.toml"
    path.write_text(SCENE)
    report = run_scene(load_scene(path), out, log=lambda _: None, progress=False)
    page = _Page()
    text = (out / "servo_html_report.html").read_text(encoding="utf-8")
    page.feed(text)
    return report, page, text, out


def test_page_is_self_contained(run):
    report, page, text, out = run
    assert (out / "servo_html_report.html") in report.files
    for tag, attrs in page.tags:
        assert tag not in ("link", "iframe", "object", "embed"), tag
        for key in ("src", "href"):
            if key in attrs:
                assert attrs[key].startswith("data:"), f"<{tag} {key}={attrs[key][:40]!r}> fetches a resource"
    assert not re.search(r"https?://", text)
    assert "&lt;check &amp; escape&gt;" in text  # the title is escaped, not markup


def test_cycle_table_holds_the_runs_numbers(run):
    report, page, _, _ = run
    rows = page.cells["cycles"][2:]  # two header rows
    assert len(rows) == len(report.cycles) == 2
    for row, c, v in zip(rows, report.cycles, report.verifications):
        assert float(row[1]) == pytest.approx(c.amplitude, rel=1e-5)
        assert float(row[2]) == pytest.approx(c.frequency, rel=1e-5)
        assert row[3] == c.stability and row[11] == v.verdict
        if c.exact.success:
            assert float(row[7]) == pytest.approx(c.exact.amplitude, rel=1e-5)
        else:
            assert row[7] == "-" and row[9].startswith(c.verdict.kind + " (note")
    # the stable cycle: predicted, exact and verified agree on "stable"; the verification settles on the exact
    # orbit's amplitude (shooting and forward simulation are independent algorithms)
    stable = next(i for i, c in enumerate(report.cycles) if c.stable)
    row = rows[stable]
    assert "stable" in row[9] and row[11] == "stable"
    settled = float(re.search(r"X=([0-9.]+)", row[12]).group(1))  # Backlash: the input is X [m]
    assert settled == pytest.approx(report.cycles[stable].exact.amplitude, rel=1e-3)
    assert page.cells["cycles"][1][0] == "X [m]"  # amplitudes named and measured as the element's input
    assert {"settings", "timings"} <= set(page.cells)
    timed = {r[0] for r in page.cells["timings"][1:-1]}
    assert timed == {name for name, _ in report.stages}


def test_every_figure_is_embedded_and_decodes(run):
    report, page, _, _ = run
    from io import BytesIO

    from PIL import Image

    images = [attrs["src"] for tag, attrs in page.tags if tag == "img"]
    pngs = [p for p in report.files if p.suffix == ".png"]
    assert len(images) == len(pngs) + len(report.verifications)
    data = [base64.b64decode(src.split(",", 1)[1]) for src in images]
    for path, blob in zip(pngs, data):
        assert blob == path.read_bytes()  # the file on disk, byte for byte
    for blob in data:
        with Image.open(BytesIO(blob)) as im:
            assert im.format == "PNG" and im.size[0] > 200 and im.size[1] > 200

"""Open a scene's HTML report in a real browser (headless Chromium) and check what a person would check.

Not a pytest module (the README's test command needs no browser); ``.ci/run`` runs it after the tests:

    python tests/browser/check_report.py [--scene backlash_servo] [--out DIR] [--browser chromium]

Steps: run the scene (``run_scene``) into ``--out``; load ``<scene>_report.html`` from disk (``file://``, no
server) in headless Chromium; a copy of the page carries a small inline script that, after the load event, writes
what the browser measured into the DOM (every image's ``complete`` / ``naturalWidth``, the tables present, the
rows of the cycle table, the page's scroll width against the window's width, each table's scroll width against
its box), which ``--dump-dom`` returns; a screenshot of the original page is taken too (``--screenshot``).

Asserted: the cycle table is there with one row per predicted cycle and the settings and timings tables exist;
every figure decoded (naturalWidth > 0; as many figures as the run produced); nothing overflows the page width
at 1280 px, and no table is wider than its box; the screenshot is a real picture (not blank). Exit status 1 with
the reasons otherwise. The screenshot's path is printed: look at it.
"""
from __future__ import annotations

import argparse
import html
import json
import os
import re
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

WIDTH, HEIGHT = 1280, 2400
TIMEOUT = 180  # seconds per browser call

PROBE = """
<script>
window.addEventListener("load", function () {
  var doc = document.documentElement;
  var result = {
    images: Array.from(document.images).map(function (im) {
      return {alt: im.alt, complete: im.complete, naturalWidth: im.naturalWidth, naturalHeight: im.naturalHeight,
              right: im.getBoundingClientRect().right};
    }),
    tables: Array.from(document.querySelectorAll("table")).map(function (t) { return t.id; }),
    cycleRows: document.querySelectorAll("#cycles tr").length,
    scrollWidth: doc.scrollWidth, innerWidth: window.innerWidth,
    wideBoxes: Array.from(document.querySelectorAll(".scroll, pre")).filter(function (b) {
      return b.scrollWidth > b.clientWidth + 1;
    }).map(function (b) { return (b.firstElementChild && b.firstElementChild.id) || b.tagName; })
  };
  var out = document.createElement("pre");
  out.id = "dfloop-check";
  out.textContent = JSON.stringify(result);
  document.body.appendChild(out);
});
</script>
"""


def browser_command(browser: str, profile: str) -> list[str]:
    return [browser, "--headless", "--no-sandbox", "--disable-gpu", "--disable-background-networking",
            "--disable-component-update", "--disable-sync", "--no-first-run", "--hide-scrollbars",
            f"--user-data-dir={profile}", f"--window-size={WIDTH},{HEIGHT}", "--virtual-time-budget=15000"]


def run(cmd: list[str]) -> str:
    done = subprocess.run(cmd, capture_output=True, text=True, timeout=TIMEOUT)
    if done.returncode != 0:
        raise RuntimeError(f"{cmd[0]} failed ({done.returncode}): {done.stderr[-2000:]}")
    return done.stdout


def check(scene_name: str, out: Path, browser: str) -> tuple[list[str], Path]:
    import matplotlib

    matplotlib.use("Agg")
    from dfloop.scene import load_scene, run_scene

    report = run_scene(load_scene(scene_name), out, log=lambda _: None, progress=False)
    page = out / f"{report.scene.name}_report.html"
    expected_figures = sum(p.suffix == ".png" for p in report.files) + len(report.verifications)
    n_cycles = len(report.cycles) if report.cycles is not None else 0

    probe = page.with_name(page.stem + "_probe.html")
    probe.write_text(page.read_text(encoding="utf-8").replace("</body>", PROBE + "</body>"), encoding="utf-8")
    shot = out / f"{report.scene.name}_report_screenshot.png"
    problems = []
    with tempfile.TemporaryDirectory(prefix="dfloop-chromium-") as profile:
        dom = run(browser_command(browser, profile) + ["--dump-dom", probe.resolve().as_uri()])
        run(browser_command(browser, profile) + [f"--screenshot={shot}", page.resolve().as_uri()])
    found = re.search(r'<pre id="dfloop-check">(.*?)</pre>', dom, re.S)
    if not found:
        return ["the page's check script did not run (no #dfloop-check in the DOM after load)"], shot
    r = json.loads(html.unescape(found.group(1)))

    for table in ("cycles", "settings", "timings"):
        if table not in r["tables"] and (table != "cycles" or n_cycles):
            problems.append(f"table #{table} missing (tables: {r['tables']})")
    if n_cycles and r["cycleRows"] != n_cycles + 2:  # two header rows
        problems.append(f"cycle table has {r['cycleRows'] - 2} rows, the run predicted {n_cycles} cycles")
    if len(r["images"]) != expected_figures:
        problems.append(f"{len(r['images'])} figures on the page, the run produced {expected_figures}")
    for im in r["images"]:
        if not (im["complete"] and im["naturalWidth"] > 0 and im["naturalHeight"] > 0):
            problems.append(f"figure {im['alt']!r} did not load ({im})")
        if im["right"] > r["innerWidth"] + 1:
            problems.append(f"figure {im['alt']!r} runs past the window ({im['right']:.0f} > {r['innerWidth']})")
    if r["scrollWidth"] > r["innerWidth"]:
        problems.append(f"the page is wider than the window: {r['scrollWidth']} > {r['innerWidth']} px")
    if r["wideBoxes"]:
        problems.append(f"boxes wider than the page column (need horizontal scrolling): {r['wideBoxes']}")

    from PIL import Image

    if not shot.exists():
        problems.append("no screenshot written")
    else:
        with Image.open(shot) as img:
            small = img.convert("RGB").resize((160, 300))
            colors = len(set(small.tobytes()[k:k + 3] for k in range(0, 160 * 300 * 3, 3)))
            if img.size != (WIDTH, HEIGHT) or colors < 50:
                problems.append(f"screenshot {img.size} with {colors} colours: blank or wrong size")
    print(f"{page.name}: {n_cycles} cycles, {len(r['images'])} figures "
          f"({', '.join(str(im['naturalWidth']) + 'x' + str(im['naturalHeight']) for im in r['images'])}), "
          f"page width {r['scrollWidth']} px in a {r['innerWidth']} px window; screenshot {shot}")
    return problems, shot


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--scene", default="backlash_servo", help="shipped scene name or TOML path")
    parser.add_argument("--out", default=None, help="output folder (default: a temporary one, kept)")
    parser.add_argument("--browser", default=os.environ.get("DFLOOP_BROWSER", "chromium"))
    args = parser.parse_args(argv)
    browser = shutil.which(args.browser)
    if browser is None:
        print(f"browser {args.browser!r} not found (apt-get install -y chromium)", file=sys.stderr)
        return 1
    out = Path(args.out) if args.out else Path(tempfile.mkdtemp(prefix="dfloop-report-"))
    out.mkdir(parents=True, exist_ok=True)
    problems, shot = check(args.scene, out, browser)
    for p in problems:
        print("FAIL:", p, file=sys.stderr)
    print("report check:", "FAILED" if problems else "passed", f"(look at {shot})")
    return 1 if problems else 0


if __name__ == "__main__":
    sys.exit(main())

"""The report in a real browser: headless Chromium opens it, zooms, shows a track, localises the
events table's times, and draws it (screenshot); the ``--geojson`` export, loaded as written by a
small self-contained page, is drawn too (every line and flagged fix counted, their colours found
in the screenshot).

Chromium comes from Debian's package (`apt-get install -y chromium`; .ci/run installs it).
Where it is missing and cannot be installed here, the test is skipped saying so.
"""

from __future__ import annotations

import os
import re
import shutil
import subprocess
from pathlib import Path

import pytest
from click.testing import CliRunner

from gradgps._cli import main
from gradgps._data.inject import inject_grad
from gradgps._data.simulator import simulate_fleet

pytest.importorskip("matplotlib")


def _chromium() -> str:
    for name in ("chromium", "chromium-browser"):
        found = shutil.which(name)
        if found:
            return found
    if os.environ.get("CI") and shutil.which("apt-get") and os.geteuid() == 0:
        # The test setup installs it when it can (CI runs as root); .ci/run does so first.
        subprocess.run(
            ["apt-get", "install", "-y", "-qq", "chromium"],
            check=False,
            capture_output=True,
            timeout=600,
        )
        found = shutil.which("chromium")
        if found:
            return found
    pytest.skip(
        "headless-browser test skipped: Chromium is not installed "
        "(Debian: apt-get update && apt-get install -y chromium; .ci/run does this)"
    )


def _run_chromium(chromium: str, args: list[str], tz: str) -> subprocess.CompletedProcess[str]:
    env = {**os.environ, "TZ": tz}
    return subprocess.run(
        [
            chromium,
            "--headless",
            "--no-sandbox",
            "--disable-gpu",
            "--disable-dev-shm-usage",
            "--no-first-run",
            "--virtual-time-budget=3000",
            *args,
        ],
        env=env,
        capture_output=True,
        text=True,
        timeout=120,
        check=False,
    )


@pytest.mark.slow
def test_report_opens_zooms_and_shows_local_event_times(tmp_path: Path) -> None:
    chromium = _chromium()
    drives = inject_grad(simulate_fleet(2, 4.0, 1.0, 11), seed=1)
    source = tmp_path / "in.csv"
    drives[["track", "t", "lat", "lon", "speed"]].to_csv(source, index=False)
    report = tmp_path / "report.html"
    run = CliRunner().invoke(
        main,
        ["detect", str(source), "--threshold", "0.2", "--report", str(report)],
    )
    assert run.exit_code == 0, run.output
    page = report.read_text()
    original = re.search(r"data-track='1'[^>]*>\s*<svg[^>]*viewBox='([^']+)'", page)
    assert original is not None
    width = float(original.group(1).split()[2])

    url = report.as_uri() + "#track=1&zoom=4"
    dom = _run_chromium(chromium, ["--dump-dom", url], tz="Asia/Tokyo")
    assert dom.returncode == 0, dom.stderr[-2000:]
    html = dom.stdout
    assert 'data-ready="1"' in html  # the script ran to its end without an error
    # Track 1 shown, track 0 hidden, its view zoomed 4x.
    shown = re.search(r'<div class="track-view" data-track="1">\s*<svg[^>]*viewBox="([^"]+)"', html)
    assert shown is not None, "track 1 is not the visible track"
    assert re.search(r'<div class="track-view" data-track="0" hidden', html)
    assert float(shown.group(1).split()[2]) == pytest.approx(width / 4, rel=1e-3)
    # Events table: times rewritten in the viewer's zone (UTC+9), the UTC text kept as tooltip.
    table = re.search(r'<table id="events-table">(.*?)</table>', html, re.S)
    assert table is not None
    cells = re.findall(r'<time data-t="([^"]+)" title="([^"]+)">([^<]+)</time>', table.group(1))
    assert cells, "no localised times in the events table"
    t, utc_text, local_text = cells[0]
    assert utc_text.endswith("UTC")
    assert local_text != utc_text
    import datetime as dt

    local = dt.datetime.fromtimestamp(float(t), dt.timezone(dt.timedelta(hours=9)))
    assert f"{local:%H:%M:%S}" in local_text

    shot = tmp_path / "shot.png"
    drawn = _run_chromium(
        chromium, [f"--screenshot={shot}", "--window-size=1300,2400", url], tz="UTC"
    )
    assert drawn.returncode == 0, drawn.stderr[-2000:]
    assert shot.stat().st_size > 20_000  # a drawn page, not a blank one


#: Colours the GeoJSON page draws with: the repaired track's lines, the flagged fixes.
LINE_RGB = (214, 39, 40)
POINT_RGB = (31, 119, 180)

#: A self-contained page (no network, no file fetch) that draws a GeoJSON document as SVG:
#: LineStrings as polylines, Points as dots, in an equirectangular view of their bounds, and
#: says on <body> how many of each it drew.
_GEOJSON_PAGE = """<!doctype html><html><head><meta charset="utf-8"><style>
body {{ margin: 0; background: #fff; }} svg {{ width: 1000px; height: 1000px; }}
</style></head><body><svg id="map" xmlns="http://www.w3.org/2000/svg"></svg>
<script type="application/geo+json" id="doc">{doc}</script>
<script>
var doc = JSON.parse(document.getElementById("doc").textContent);
var svg = document.getElementById("map"), ns = "http://www.w3.org/2000/svg";
var xs = [], ys = [];
function each(g, f) {{
  if (g.type === "Point") f(g.coordinates);
  else if (g.type === "LineString" || g.type === "MultiPoint") g.coordinates.forEach(f);
  else if (g.type === "MultiLineString") g.coordinates.forEach(function (l) {{ l.forEach(f); }});
}}
doc.features.forEach(function (ft) {{
  if (ft.geometry) each(ft.geometry, function (c) {{ xs.push(c[0]); ys.push(c[1]); }});
}});
var x0 = Math.min.apply(null, xs), x1 = Math.max.apply(null, xs);
var y0 = Math.min.apply(null, ys), y1 = Math.max.apply(null, ys);
var k = Math.cos((y0 + y1) / 2 * Math.PI / 180), span = Math.max((x1 - x0) * k, y1 - y0) || 1;
function px(c) {{ return [20 + 960 * (c[0] - x0) * k / span, 980 - 960 * (c[1] - y0) / span]; }}
var lines = 0, points = 0;
function line(coords) {{
  var el = document.createElementNS(ns, "polyline");
  el.setAttribute("points", coords.map(function (c) {{ return px(c).join(","); }}).join(" "));
  el.setAttribute("fill", "none"); el.setAttribute("stroke", "rgb({line})");
  el.setAttribute("stroke-width", "6"); svg.appendChild(el); lines++;
}}
doc.features.forEach(function (ft) {{
  var g = ft.geometry;
  if (!g) return;
  if (g.type === "LineString") line(g.coordinates);
  else if (g.type === "MultiLineString") g.coordinates.forEach(line);
  else if (g.type === "Point") {{
    var p = px(g.coordinates), el = document.createElementNS(ns, "circle");
    el.setAttribute("cx", p[0]); el.setAttribute("cy", p[1]); el.setAttribute("r", "7");
    el.setAttribute("fill", "rgb({point})"); svg.appendChild(el); points++;
  }}
}});
document.body.setAttribute("data-drawn", lines + "," + points);
</script></body></html>
"""


def _colour_pixels(png: Path, rgb: tuple[int, int, int]) -> int:
    import matplotlib.image as mpimg
    import numpy as np

    image = mpimg.imread(png)[..., :3]
    target = np.asarray(rgb, dtype=float) / 255.0
    return int((np.abs(image - target).max(axis=-1) < 0.03).sum())


@pytest.mark.slow
def test_geojson_export_is_drawn_in_a_browser(tmp_path: Path) -> None:
    """The ``--geojson`` output, as written, renders: every line and flagged fix, in colour."""
    import json

    chromium = _chromium()
    drives = inject_grad(simulate_fleet(2, 3.0, 1.0, 5), seed=1)
    source = tmp_path / "in.csv"
    drives[["track", "t", "lat", "lon", "speed"]].to_csv(source, index=False)
    geojson = tmp_path / "out.geojson"
    run = CliRunner().invoke(
        main, ["detect", str(source), "--threshold", "0.2", "--geojson", str(geojson)]
    )
    assert run.exit_code == 0, run.output
    text = geojson.read_text(encoding="utf-8")
    doc = json.loads(text)
    kinds = [f["geometry"]["type"] for f in doc["features"] if f.get("geometry")]
    n_lines = sum(
        1 if k == "LineString" else len(f["geometry"]["coordinates"])
        for f, k in zip(doc["features"], kinds, strict=True)
        if k in ("LineString", "MultiLineString")
    )
    n_points = kinds.count("Point")
    assert n_lines >= 2  # one repaired track per drive at least
    assert n_points >= 1  # the injected faults are flagged
    page = tmp_path / "geojson.html"
    page.write_text(
        _GEOJSON_PAGE.format(
            doc=text.replace("</", "<\\/"),
            line=",".join(map(str, LINE_RGB)),
            point=",".join(map(str, POINT_RGB)),
        ),
        encoding="utf-8",
    )
    dom = _run_chromium(chromium, ["--dump-dom", page.as_uri()], tz="UTC")
    assert dom.returncode == 0, dom.stderr[-2000:]
    drawn = re.search(r'data-drawn="(\d+),(\d+)"', dom.stdout)
    assert drawn is not None, "the page's script did not finish drawing the GeoJSON"
    assert (int(drawn.group(1)), int(drawn.group(2))) == (n_lines, n_points)
    shot = tmp_path / "geojson.png"
    taken = _run_chromium(
        chromium, [f"--screenshot={shot}", "--window-size=1000,1000", page.as_uri()], tz="UTC"
    )
    assert taken.returncode == 0, taken.stderr[-2000:]
    assert _colour_pixels(shot, LINE_RGB) > 500  # the repaired tracks are drawn
    assert _colour_pixels(shot, POINT_RGB) > 50  # and the flagged fixes on them

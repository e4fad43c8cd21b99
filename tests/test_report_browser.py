"""The report in a real browser: headless Chromium opens it, zooms, shows a track, localises the
events table's times, and draws it (screenshot); the report draws the ``--geojson`` document it
embeds (every repaired line and flagged fix counted against the document, in its track's view with
its verdict as tooltip, their colours found in the screenshot of the track view).

Chromium comes from Debian's package (`apt-get install -y chromium`; .ci/run installs it).
Where it is missing and cannot be installed here, the test is skipped saying so.
"""

from __future__ import annotations

import os
import re
import shutil
import subprocess
from pathlib import Path
from typing import Any

import pytest
from click.testing import CliRunner

from _report_support import report_and_geojson
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


def _colour_pixels(image: Any, rgb: str) -> int:
    import numpy as np

    target = np.asarray([int(rgb[k : k + 2], 16) for k in (1, 3, 5)], dtype=float) / 255.0
    return int((np.abs(image - target).max(axis=-1) < 0.03).sum())


def _track_view(png: Path) -> Any:
    """The screenshot cropped to the shown track's SVG: the region of its #fcfcfc background
    (the static figures below, drawn in the same colours, are left out)."""
    import matplotlib.image as mpimg
    import numpy as np

    image = mpimg.imread(png)[..., :3]
    background = np.abs(image - 252 / 255).max(axis=-1) < 0.002
    rows = np.flatnonzero(background.sum(axis=1) > 0.5 * background.shape[1])
    assert rows.size > 200, "no track view in the screenshot"
    cols = np.flatnonzero(background[rows.min() : rows.max() + 1].sum(axis=0) > 0.5 * rows.size)
    return image[rows.min() : rows.max() + 1, cols.min() : cols.max() + 1]


@pytest.mark.slow
def test_report_draws_its_embedded_geojson(tmp_path: Path) -> None:
    """The report draws the ``--geojson`` document it embeds: every repaired line and flagged
    fix, in the track view of its track, in colour (screenshot), with a verdict to hover."""
    import json

    chromium = _chromium()
    report, geojson = report_and_geojson(tmp_path)
    page = report.read_text(encoding="utf-8")
    block = re.search(r"<script type='application/geo\+json' id='geojson'>([^<]*)</script>", page)
    assert block is not None, "the report embeds no GeoJSON"
    doc = json.loads(block.group(1))
    assert doc == json.loads(geojson.read_text(encoding="utf-8"))

    def geometry_parts(kind: str, track: str | None = None) -> list[Any]:
        parts: list[Any] = []
        for f in doc["features"]:
            g, p = f["geometry"], f["properties"]
            if g is None or p["kind"] != kind or (track is not None and p["track"] != track):
                continue
            if g["type"] == "MultiLineString":
                parts.extend(g["coordinates"])
            elif g["type"] in ("LineString", "Point"):
                parts.append(f)
        return parts

    n_lines = len(geometry_parts("repaired track"))
    n_points = len(geometry_parts("flagged fix"))
    assert n_lines >= 2  # one repaired line per drive at least
    assert n_points >= 1  # the injected faults are flagged

    url = report.as_uri() + "#track=1"
    dom = _run_chromium(chromium, ["--dump-dom", url], tz="UTC")
    assert dom.returncode == 0, dom.stderr[-2000:]
    html = dom.stdout
    assert 'data-ready="1"' in html
    drawn = re.search(r'data-geojson-drawn="(\d+),(\d+)"', html)
    assert drawn is not None, "the report's script did not draw the GeoJSON"
    assert (int(drawn.group(1)), int(drawn.group(2))) == (n_lines, n_points)
    # Each in its own track's view: the selector, zoom and hover apply to them.
    for track in ("0", "1"):
        view = re.search(
            rf'<div class="track-view" data-track="{track}"[^>]*>(.*?)</div>', html, re.S
        )
        assert view is not None
        assert view.group(1).count('class="clean"') == len(geometry_parts("repaired track", track))
        dots = geometry_parts("flagged fix", track)
        assert view.group(1).count("<circle") == len(dots)
        first = dots[0]["properties"]
        assert f"<title>row {first['row']}, " in view.group(1)  # the verdict, on hover
        assert f"{first['score']:.3f}, {first['bias_type']} / {first['time_type']}" in view.group(1)

    from gradgps._run.explore import CLEAN_COLOUR, COLOURS

    shot = tmp_path / "shot.png"
    taken = _run_chromium(
        chromium, [f"--screenshot={shot}", "--window-size=1300,2400", url], tz="UTC"
    )
    assert taken.returncode == 0, taken.stderr[-2000:]
    view_png = _track_view(shot)
    assert _colour_pixels(view_png, CLEAN_COLOUR) > 300  # the repaired line of track 1
    shown = [f["properties"]["bias_type"] for f in geometry_parts("flagged fix", "1")]
    for bias in {b for b in shown if b in COLOURS and shown.count(b) >= 3}:
        assert _colour_pixels(view_png, COLOURS[bias]) > 40, bias  # its flagged fixes
    assert any(shown.count(b) >= 3 for b in COLOURS)

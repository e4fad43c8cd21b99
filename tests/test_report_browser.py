"""The report in a real browser: headless Chromium opens it, zooms, shows a track, localises the
events table's times, and draws it (screenshot).

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

"""HTML report and PNG plots: self-contained, small, with the sections a reader looks for."""

from __future__ import annotations

import re
import warnings

import numpy as np
import pandas as pd
import pytest
from click.testing import CliRunner

from gradgps._cli import main
from gradgps._data.inject import inject_grad
from gradgps._data.simulator import simulate_drive, simulate_fleet
from gradgps._grad.detector import Detector
from gradgps._run.report import rema_bounds
from gradgps._tracks.preprocess import preprocess

pytest.importorskip("matplotlib")


def test_demo_report_for_10000_points_is_offline_and_small(tmp_path):
    out = tmp_path / "demo"
    # One drive of 167 min at 1 Hz: 10,020 fixes.
    result = CliRunner().invoke(
        main, ["demo", "--tracks", "1", "--minutes", "167", "--out", str(out)]
    )
    assert result.exit_code == 0, result.output
    report = out / "report.html"
    assert f"report: {report}" in result.output.replace("\n", "")
    size = report.stat().st_size
    assert size < 5e6
    text = report.read_text(encoding="utf-8")
    for section in (
        "id='summary'",
        "id='track'",
        "id='channels'",
        "id='anomalies'",
        "REMA bounds",
        "input rows",
        "by bias type",
        "alerts",
        "throughput",
    ):
        assert section in text
    assert "<td>10,020</td>" in text
    assert text.count("src='data:image/png;base64,") >= 2
    # Nothing fetched from the network: no external src/href, no script from anywhere.
    assert not re.search(r"""(src|href)\s*=\s*['"]?(https?:)?//""", text)
    # One small inline script (zoom, track selector, local times): nothing loaded from anywhere.
    assert text.count("<script") == 1
    assert not re.search(r"<script[^>]*\ssrc", text)
    assert not re.search(r"fetch\(|XMLHttpRequest|import\(", text)


def test_detect_writes_report_and_plots(tmp_path):
    drives = inject_grad(simulate_fleet(2, 4.0, 1.0, 11), seed=1)
    source = tmp_path / "in.csv"
    drives[["track", "t", "lat", "lon", "speed", "heading"]].to_csv(source, index=False)
    plots = tmp_path / "plots"
    result = CliRunner().invoke(
        main,
        [
            "detect",
            str(source),
            "-o",
            str(tmp_path / "o.csv"),
            "--report",
            str(tmp_path / "r.html"),
            "--plots",
            str(plots),
        ],
    )
    assert result.exit_code == 0, result.output
    names = sorted(p.name for p in plots.iterdir())
    assert names[-1] == "track.png"
    assert any(n.startswith("channels_segment") for n in names)
    assert all((plots / n).read_bytes()[:8] == b"\x89PNG\r\n\x1a\n" for n in names)
    assert "in.csv" in (tmp_path / "r.html").read_text(encoding="utf-8")


def test_report_with_hostile_track_ids_and_fixes_a_nanosecond_apart(tmp_path):
    # Issue 18, item 7: an id like $\\foo$ went to matplotlib as mathtext and the
    # report died with a traceback; ids are the user's text, shown as typed.
    ids = ["$\\foo$", '<script>alert("x")</script>', "quo\"te's & ünï 北京 😀", "ns"]
    rows = []
    for k, track in enumerate(ids):
        for i in range(40):
            t = i * 1e-9 if track == "ns" else 1.7e9 + i  # one track 1 ns apart
            rows.append((track, t, 48.1 + 1e-3 * k + 1e-4 * i, 11.5 + 1e-4 * i))
    source = tmp_path / "ids.csv"
    pd.DataFrame(rows, columns=["track", "time", "lat", "lon"]).to_csv(source, index=False)
    report = tmp_path / "r.html"
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        result = CliRunner().invoke(
            main,
            ["detect", str(source), "-o", str(tmp_path / "o.csv"), "--report", str(report)],
        )
    assert result.exit_code == 0, result.output
    assert result.exception is None
    assert not [w for w in caught if "Glyph" in str(w.message)]
    text = report.read_text(encoding="utf-8")
    assert "<script>alert(" not in text
    assert "&lt;script&gt;alert(&quot;x&quot;)&lt;/script&gt;" in text
    assert "Track $\\foo$, segment" in text  # a figure of that track was drawn
    assert "quo&quot;te&#x27;s &amp; ünï 北京 😀" in text
    assert text.count("<script") == 1
    assert text.count("src='data:image/png;base64,") >= 2


def test_follow_refuses_report():
    result = CliRunner().invoke(main, ["detect", "--follow", "-", "--report", "r.html"], input="")
    assert result.exit_code == 2
    assert "need a whole file" in result.output


def test_bounds_are_the_pipelines_own_and_hold_clean_points():
    """On the first clean minute, every point lies inside the REMA bounds (after the warm-up)."""
    detector = Detector()
    params = detector.model_.params
    drive = simulate_drive(minutes=1.0, seed=5)
    prepared = preprocess(drive, max_gap_s=params.max_gap_s, interpolate=False)
    (bounds,) = rema_bounds(prepared, params, np.zeros(len(prepared.points), bool), [0])
    warm = params.rema.slide_size
    assert np.all(np.isnan(bounds.east_lower[:1]))
    inside = (bounds.east[warm:] >= bounds.east_lower[warm:]) & (
        bounds.east[warm:] <= bounds.east_upper[warm:]
    )
    assert inside.mean() > 0.9
    half = 0.5 * (bounds.north_upper[warm:] - bounds.north_lower[warm:])
    assert np.all(half >= params.rema.min_margin - 1e-9)


def test_report_rema_on_positions_only_follows_the_track_at_half_hz():
    """Positions only at 0.5 Hz: the report's REMA is the detector's (driven by the motion
    model's velocity), so its prediction stays on a clean track. It used to run REMA
    without that velocity and drew a prediction hundreds of metres off the track
    (the Nevada Garmin drive, positions only)."""
    from gradgps._grad.defaults import grad_points

    params = Detector().model_.params
    fleet = simulate_fleet(2, 20.0, 0.5, 11, imu=False)[["track", "t", "lat", "lon"]]
    prepared = grad_points(fleet, params.max_gap_s)
    segments = [k for k, _ in prepared.segment_slices()]
    flags = np.zeros(len(prepared.points), bool)
    for b in rema_bounds(prepared, params, flags, segments):
        warm = params.rema.slide_size
        for obs, lo, hi in (
            (b.east, b.east_lower, b.east_upper),
            (b.north, b.north_lower, b.north_upper),
        ):
            miss = np.abs(obs - 0.5 * (lo + hi))[warm:]
            assert np.nanmax(miss) < 100.0  # a clean track: never far from REMA's prediction

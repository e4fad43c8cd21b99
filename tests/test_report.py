"""HTML report and PNG plots: self-contained, small, with the sections a reader looks for."""

from __future__ import annotations

import json
import re
import warnings
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from click.testing import CliRunner

from _report_support import report_and_geojson
from gradgps._cli import main
from gradgps._data.inject import inject_grad
from gradgps._data.simulator import simulate_drive, simulate_fleet
from gradgps._grad.detector import Detector
from gradgps._run.report import rema_bounds
from gradgps._tracks.preprocess import preprocess
from test_export import validate_geojson

pytest.importorskip("matplotlib")

_GEOJSON_BLOCK = re.compile(
    r"<script type='application/geo\+json' id='geojson'( data-thinned='1')?>([^<]*)</script>"
)


def _embedded(page: str) -> str:
    """The text of the report's embedded GeoJSON block (its JSON escapes as written)."""
    found = _GEOJSON_BLOCK.search(page)
    assert found is not None, "the report embeds no GeoJSON"
    return found.group(2)


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
    # One small inline script (zoom, track selector, local times) and the run's GeoJSON as a
    # data block: nothing loaded from anywhere.
    assert text.count("<script>") == 1
    assert text.count("<script") == 2
    assert text.count("<script type='application/geo+json' id='geojson'>") == 1
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
    # The ids are in the embedded GeoJSON too, as JSON escapes that cannot end its element.
    assert text.count("<script>") == 1
    assert text.count("</script>") == 2
    doc = json.loads(_embedded(text))
    validate_geojson(doc)
    drawn = {f["properties"]["track"] for f in doc["features"] if f["geometry"] is not None}
    assert drawn == set(ids)
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


def test_report_embeds_the_very_geojson_that_geojson_writes(tmp_path: Path) -> None:
    """`detect --report --geojson`: the report's embedded document is the file, byte for byte
    (once its JSON escapes of <, > and & are read back), and strict RFC 7946."""
    report, geojson = report_and_geojson(tmp_path)
    page = report.read_text(encoding="utf-8")
    written = geojson.read_text(encoding="utf-8")
    block = _embedded(page)
    assert "data-thinned" not in page  # a small file is embedded whole
    assert json.loads(block) == json.loads(written)
    unescaped = block.replace("\\u003c", "<").replace("\\u003e", ">").replace("\\u0026", "&")
    assert unescaped == written
    doc = json.loads(block)
    validate_geojson(doc)
    kinds = [f["properties"]["kind"] for f in doc["features"]]
    assert kinds.count("repaired track") >= 2  # both drives
    assert kinds.count("flagged fix") >= 1
    assert kinds.count("event") >= 1
    # The view is drawn from it by the page's script, not drawn a second time in the HTML.
    assert "class='clean'" not in page
    assert "<circle" not in page
    assert page.count("data-origin=") == 2


def _big_run(n_tracks: int, n: int) -> tuple[pd.DataFrame, pd.DataFrame]:
    """A synthetic run: ``n`` fixes per track, every third one flagged, a gap in the middle."""
    rows = np.arange(n)
    fixes = pd.concat(
        [
            pd.DataFrame(
                {
                    "track": f"car {k}",
                    "t": 1.7e9 + rows + np.where(rows >= n // 2, 600.0, 0.0),
                    "lat": 48.1 + 1e-5 * rows + 1e-3 * k,
                    "lon": 11.5 + 2e-5 * rows,
                }
            )
            for k in range(n_tracks)
        ],
        ignore_index=True,
    )
    m = len(fixes)
    flagged = (np.arange(m) % 3 == 0).astype(int)
    result = pd.DataFrame(
        {
            "anomaly": flagged,
            "score": np.where(flagged == 1, 0.9, 0.1),
            "bias_type": np.where(flagged == 1, "jump", "none"),
            "time_type": np.where(flagged == 1, "transient", "none"),
            "alert": np.zeros(m, int),
            "lat_clean": fixes["lat"] - 1e-6,
            "lon_clean": fixes["lon"],
            "invalid_reason": "",
        }
    )
    return fixes, result


def test_embedded_geojson_is_whole_when_small_and_thinned_when_big(monkeypatch):
    from gradgps._io.export import geojson_document, geojson_text
    from gradgps._run import explore

    fixes, result = _big_run(2, 3_000)
    doc = geojson_document(fixes, result)
    block, note = explore.embedded_geojson(doc)
    assert "data-thinned" not in block
    assert json.loads(_embedded(block)) == doc
    assert "the same document gradgps detect --geojson writes" in note

    monkeypatch.setattr(explore, "MAX_EMBEDDED_CHARS", len(geojson_text(doc)) - 1)
    monkeypatch.setattr(explore, "MAX_LINE_VERTICES", 500)
    monkeypatch.setattr(explore, "MAX_DOTS", 200)
    block, note = explore.embedded_geojson(doc)
    assert "data-thinned='1'" in block
    assert "thinned copy" in note
    assert "--geojson writes every fix" in note
    small = json.loads(_embedded(block))
    validate_geojson(small)
    assert len(block) < len(geojson_text(doc)) / 4
    for track in ("car 0", "car 1"):
        lines = [
            f["geometry"]["coordinates"]
            for f in small["features"]
            if f["properties"]["kind"] == "repaired track" and f["properties"]["track"] == track
        ]
        assert len(lines) == 2  # the 600 s gap still splits the track
        assert 250 <= sum(map(len, lines)) <= 502
        full = [
            f["geometry"]["coordinates"]
            for f in doc["features"]
            if f["properties"]["kind"] == "repaired track" and f["properties"]["track"] == track
        ]
        for thin, whole in zip(lines, full, strict=True):  # ends kept
            assert thin[0] == pytest.approx(whole[0], abs=1e-7)
            assert thin[-1] == pytest.approx(whole[-1], abs=1e-7)
        dots = [
            f
            for f in small["features"]
            if f["properties"]["kind"] == "flagged fix" and f["properties"]["track"] == track
        ]
        assert len(dots) == 200
        rows = [f["properties"]["row"] for f in dots]
        assert rows == sorted(rows)
        span = max(rows) - min(rows)
        assert span > 0.95 * 3_000  # spread over the whole track, not its first fixes

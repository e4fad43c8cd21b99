"""``--report`` of a long run in bounded memory (issue 18): past ``EXACT_ROWS`` rows the
report keeps exact counts and tables and draws from a thinned sample; up to it, it is
the report of the whole result."""

from __future__ import annotations

import json
import re
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from click.testing import CliRunner

from _whole_file import detect_whole
from gradgps._cli import main
from gradgps._data.inject import inject_grad
from gradgps._data.simulator import simulate_fleet
from gradgps._run import report_data
from gradgps._run.report_data import ReportCollector

pytest.importorskip("matplotlib")


@pytest.fixture(scope="module")
def fleet(tmp_path_factory: pytest.TempPathFactory) -> Path:
    drives = inject_grad(simulate_fleet(4, 20.0, 1.0, seed=3), seed=2)
    path = tmp_path_factory.mktemp("fleet") / "fleet.csv"
    frame = drives[["track", "t", "lat", "lon", "speed", "heading"]].copy()
    frame.loc[frame.index[::97], "t"] = np.nan  # some invalid fixes, with their reason
    frame.to_csv(path, index=False)
    return path


def _report(path: Path, out: Path, *extra: str) -> str:
    result = CliRunner().invoke(
        main, ["detect", str(path), "--report", str(out), "--chunk-size", "997", *extra]
    )
    assert result.exit_code == 0, result.output
    return out.read_text(encoding="utf-8")


def _thin(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(report_data, "EXACT_ROWS", 500)
    monkeypatch.setattr(report_data, "SAMPLE_ROWS", 1000)
    monkeypatch.setattr(report_data, "TRACK_ROWS", 300)


def _summary(page: str) -> dict[str, str]:
    table = re.search(r"<h2 id='summary'>Summary</h2>(<table>.*?</table>)", page)
    assert table is not None
    rows = dict(re.findall(r"<tr><td>(.*?)</td><td>(.*?)</td></tr>", table.group(1)))
    rows.pop("throughput", None)
    return rows


def _section(page: str, pattern: str) -> str:
    found = re.search(pattern, page, re.S)
    assert found is not None, pattern
    return found.group(0)


def _geojson(page: str) -> dict[str, object]:
    block = _section(page, r"id='geojson'[^>]*>(.*?)</script>")
    text = block.split(">", 1)[1].rsplit("</script>", 1)[0]
    doc: dict[str, object] = json.loads(text)
    return doc


def test_a_long_run_is_thinned_with_exact_counts_and_tables(
    fleet: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    exact = _report(fleet, tmp_path / "exact.html")
    _thin(monkeypatch)
    thin = _report(fleet, tmp_path / "thin.html")
    assert "This run has 4,800 rows" in thin
    assert "This run has" not in exact
    assert "data-thinned='1'" in thin
    assert "data-thinned" not in exact
    summary = _summary(exact)
    assert "invalid fixes by reason" in summary
    assert _summary(thin) == summary
    anomalies = r"<h2 id='anomalies'>.*?</table>"
    assert _section(thin, anomalies) == _section(exact, anomalies)
    events = r"<table id='events-table'>.*?</table>"
    assert _section(thin, events) == _section(exact, events)
    captions = r"<p class='muted'>track [^<]*</p>"
    assert re.findall(captions, thin) == re.findall(captions, exact)
    whole, sampled = _geojson(exact), _geojson(thin)

    def features(doc: dict[str, object], kind: str) -> list[dict[str, object]]:
        found = doc["features"]
        assert isinstance(found, list)
        return [f for f in found if f["properties"]["kind"] == kind]

    flagged = {f["properties"]["row"]: f for f in features(whole, "flagged fix")}
    # Every flagged fix of the sample is one of the run's, with its row and verdict.
    for f in features(sampled, "flagged fix"):
        assert f == flagged[f["properties"]["row"]]
    assert len(features(sampled, "event")) == len(features(whole, "event"))
    lines = features(sampled, "repaired track")
    assert {f["properties"]["track"] for f in lines} == {
        f["properties"]["track"] for f in features(whole, "repaired track")
    }
    assert sum(f["properties"]["fixes"] for f in lines) <= 4 * 300 + len(flagged)
    assert thin.count("<img alt='channels_segment") == exact.count("<img alt='channels_segment")


def test_a_short_run_gives_the_whole_file_report(fleet: Path, tmp_path: Path) -> None:
    """Chunks of 997 rows, or the largest (``--chunk-size 0``), give the page of the file
    read whole and detected at once (``detect_whole``)."""
    chunked = _report(fleet, tmp_path / "chunked.html")
    largest = _report(fleet, tmp_path / "largest.html", "--chunk-size", "0")
    detect_whole(fleet, report=tmp_path / "whole.html")
    whole = (tmp_path / "whole.html").read_text(encoding="utf-8")

    def steady(page: str) -> str:  # the throughput and the figures' pixels aside
        page = re.sub(r"<tr><td>throughput</td><td>[^<]*</td></tr>", "", page)
        return re.sub(r"data:image/png;base64,[A-Za-z0-9+/=]*", "", page)

    assert steady(chunked) == steady(whole)
    assert steady(largest) == steady(whole)


def _chunk(offset: int, n: int, tracks: int) -> tuple[pd.DataFrame, pd.DataFrame, None]:
    rows = np.arange(offset, offset + n)
    fixes = pd.DataFrame(
        {
            "track": (rows % tracks).astype(str).astype(object),
            "t": 1.7e9 + rows // tracks,
            "lat": 48.0 + 1e-6 * rows,
            "lon": 11.0 + 1e-6 * rows,
        }
    )
    flagged = (rows % 7 == 0).astype(np.int64)
    result = pd.DataFrame(
        {
            "anomaly": flagged,
            "score": flagged * 0.9,
            "bias_type": np.where(flagged == 1, "jump", "none").astype(object),
            "time_type": np.where(flagged == 1, "transient", "none").astype(object),
            "alert": np.zeros(n, np.int64),
            "lat_clean": fixes["lat"],
            "lon_clean": fixes["lon"],
            "invalid_reason": np.where(rows % 50 == 0, "no position", "").astype(object),
        }
    )
    return fixes, result, None


def test_the_collection_stays_bounded_however_long_the_run(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(report_data, "SAMPLE_ROWS", 600)
    monkeypatch.setattr(report_data, "TRACK_ROWS", 200)
    monkeypatch.setattr(report_data, "DOT_ROWS", 300)
    collector = ReportCollector(exact_rows=1_000)
    sizes = []
    for k in range(60):
        collector.add(*_chunk(k * 997, 997, tracks=3))
        if k:
            thinning = collector._thinning
            assert thinning.lines.frame is not None
            assert thinning.dots.frame is not None
            sizes.append((len(thinning.lines.frame), len(thinning.dots.frame)))
    assert collector.whole() is None
    assert max(lines for lines, _ in sizes) <= 600
    assert max(dots for _, dots in sizes) <= 300
    thinned = collector.thinned()
    assert thinned is not None
    n = 60 * 997
    assert thinned.totals.counts.rows == n
    assert thinned.totals.usable == n - len(range(0, n, 50))
    assert np.all(np.diff(thinned.rows) > 0)
    # Evenly spread: each track's sampled fixes are every k-th of its usable ones.
    lines = collector._thinning.lines.frame
    assert lines is not None
    for _, part in lines.groupby("track"):
        steps = np.diff(part["ordinal"].to_numpy())
        assert steps.size > 50
        assert len(set(steps.tolist())) == 1


def test_an_empty_parquet_file_gets_an_empty_report(tmp_path: Path) -> None:
    path = tmp_path / "empty.parquet"
    pd.DataFrame({c: pd.Series(dtype=float) for c in ("t", "lat", "lon")}).to_parquet(path)
    page = _report(path, tmp_path / "empty.html")
    assert "<td>input rows</td><td>0</td>" in page


def test_the_sample_keeps_as_many_flagged_fixes_per_track_as_the_view_draws() -> None:
    from gradgps._run.explore import MAX_DOTS

    assert report_data.TRACK_DOTS == MAX_DOTS

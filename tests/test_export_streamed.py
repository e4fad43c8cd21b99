"""--geojson and --gpx written chunk by chunk (issue 18): the text of the whole-result writers."""

from __future__ import annotations

from pathlib import Path
from xml.sax.saxutils import escape

import numpy as np
import pandas as pd
import pytest

from _whole_file import detect_whole
from gradgps._grad.events import EventBuilder, fault_events
from gradgps._io import export_streamed
from gradgps._io.export import _lines, geojson_document, geojson_text, iso_or_none
from gradgps._io.export_streamed import StreamedExports


def _run(seed: int, n: int = 400, flagged: float = 0.3) -> tuple[pd.DataFrame, pd.DataFrame]:
    """Three interleaved tracks (one named with non-ASCII and XML characters): gaps over a
    minute, steps across the antimeridian, invalid rows, missing repairs and labels, runs
    of flagged fixes, a lone usable fix between gaps."""
    rng = np.random.default_rng(seed)
    names = np.array(["a", "b <&> ü", "c"], dtype=object)
    tracks = names[rng.integers(0, 3, n)]
    t = np.empty(n)
    clock = {k: 1_700_000_000.0 for k in names}
    for i, k in enumerate(tracks):
        clock[k] += float(rng.choice([1.0, 0.5, 120.0], p=[0.8, 0.15, 0.05]))
        t[i] = clock[k]
    lon = 179.9 + 0.2 * rng.random(n)
    lon = np.where(lon > 180.0, lon - 360.0, lon)
    lat = 48.0 + rng.random(n)
    anomaly = (rng.random(n) < flagged).astype(np.int64)
    invalid = np.where(rng.random(n) < 0.05, "latitude missing or not finite", "")
    lat_c = np.where(rng.random(n) < 0.03, np.nan, lat + 1e-5)
    lon_c = lon + rng.normal(0.0, 1e-4, n)
    fixes = pd.DataFrame({"track": tracks, "t": t, "lat": lat, "lon": lon})
    result = pd.DataFrame(
        {
            "anomaly": anomaly,
            "score": np.where(rng.random(n) < 0.05, np.nan, rng.random(n)),
            "bias_type": np.where(anomaly == 1, "jump", None),
            "time_type": np.where(anomaly == 1, "abrupt", "none"),
            "lat_clean": lat_c,
            "lon_clean": lon_c,
            "alert": (rng.random(n) < 0.1).astype(np.int64),
            "invalid_reason": invalid,
        }
    )
    return fixes, result


def _gpx_whole(fixes: pd.DataFrame, result: pd.DataFrame) -> str:
    """The GPX writer as it was before issue 18, from the whole result (the reference)."""
    t = fixes["t"].to_numpy(np.float64)
    lat_c = result["lat_clean"].to_numpy(np.float64)
    lon_c = (result["lon_clean"].to_numpy(np.float64) + 180.0) % 360.0 - 180.0
    parts = [
        '<?xml version="1.0" encoding="UTF-8"?>\n'
        '<gpx version="1.1" creator="gradgps" xmlns="http://www.topografix.com/GPX/1/1">\n'
    ]
    by_track: dict[str, list[np.ndarray]] = {}
    for track, rows in _lines(fixes, result):
        by_track.setdefault(track, []).append(rows)
    for track, runs in by_track.items():
        parts.append(f"<trk><name>{escape(track)}</name>\n")
        for rows in runs:
            parts.append("<trkseg>\n")
            for i in rows.tolist():
                when = iso_or_none(t[i])
                time_el = f"<time>{when}</time>" if when is not None else ""
                parts.append(
                    f'<trkpt lat="{lat_c[i]:.8f}" lon="{lon_c[i]:.8f}">{time_el}</trkpt>\n'
                )
            parts.append("</trkseg>\n")
        parts.append("</trk>\n")
    parts.append("</gpx>\n")
    return "".join(parts)


@pytest.mark.parametrize("seed", [0, 1, 2])
@pytest.mark.parametrize("chunk", [1, 7, 64, 10_000])
def test_streamed_exports_equal_the_whole_result_documents(
    tmp_path: Path, seed: int, chunk: int, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setattr(export_streamed._Run, "_SPILL", 50)  # long lines spill to disk too
    fixes, result = _run(seed)
    events = fault_events(fixes, result)
    assert len(events) > 5
    builder = EventBuilder()
    geo, gpx = tmp_path / "out.geojson", tmp_path / "out.gpx"
    with StreamedExports(geo, gpx) as exports:
        for start in range(0, len(fixes), chunk):
            part = slice(start, start + chunk)
            f = fixes.iloc[part].reset_index(drop=True)
            r = result.iloc[part].reset_index(drop=True)
            exports.add(f, r)
            builder.add(f, r)
        exports.finish(builder.events())
    doc = geojson_document(fixes, result, events)
    kinds = {f["geometry"]["type"] for f in doc["features"] if f["geometry"] is not None}
    assert {"Point", "LineString", "MultiLineString"} <= kinds  # every kind of line met
    assert geo.read_text(encoding="utf-8") == geojson_text(doc)
    assert gpx.read_text(encoding="utf-8") == _gpx_whole(fixes, result)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["out.geojson", "out.gpx"]


def test_streamed_exports_of_nothing_usable_and_of_no_rows(tmp_path: Path) -> None:
    fixes, result = _run(3, n=20)
    result["invalid_reason"] = "time missing or not finite"
    for f, r in ((fixes, result), (fixes.iloc[:0], result.iloc[:0])):
        with StreamedExports(tmp_path / "o.geojson", tmp_path / "o.gpx") as exports:
            exports.add(f, r)
            exports.finish(fault_events(f, r))
        assert (tmp_path / "o.geojson").read_text() == geojson_text(
            geojson_document(f, r, fault_events(f, r))
        )
        assert (tmp_path / "o.gpx").read_text() == _gpx_whole(f, r)


def test_an_error_leaves_no_file_and_no_spool(tmp_path: Path) -> None:
    fixes, result = _run(4, n=50)
    with StreamedExports(tmp_path / "o.geojson", None) as exports:
        exports.add(fixes, result)
        with pytest.raises(KeyError):
            exports.finish(pd.DataFrame({"track": ["a"]}))  # an event table without its columns
    assert list(tmp_path.iterdir()) == []


def test_detect_writes_the_same_geojson_and_gpx_in_chunks_as_whole(tmp_path: Path) -> None:
    """``gradgps detect --geojson --gpx`` in chunks of 7 rows (tracks and fault events across
    chunk boundaries) and in the largest chunks (``--chunk-size 0``) gives the bytes of the
    file read whole and detected at once (``detect_whole``)."""
    from click.testing import CliRunner

    from gradgps._cli import main
    from gradgps._data.inject import inject_grad
    from gradgps._data.simulator import simulate_fleet

    drives = inject_grad(simulate_fleet(2, 3.0, 1.0, seed=5), seed=2)
    source = tmp_path / "in.csv"
    drives[["track", "t", "lat", "lon", "speed"]].to_csv(source, index=False)
    texts = []
    for size in ("7", "0"):
        geo, gpx = tmp_path / f"{size}.geojson", tmp_path / f"{size}.gpx"
        args = ["detect", str(source), "--geojson", str(geo), "--gpx", str(gpx)]
        done = CliRunner().invoke(main, [*args, "--chunk-size", size])
        assert done.exit_code == 0, done.output
        texts.append((geo.read_bytes(), gpx.read_bytes()))
    geo, gpx = tmp_path / "whole.geojson", tmp_path / "whole.gpx"
    detect_whole(source, geojson=geo, gpx=gpx)
    assert texts[0] == texts[1] == (geo.read_bytes(), gpx.read_bytes())
    assert texts[0][0].count(b'"kind":"event"') > 2


def _export_peak_mb(tmp_path: Path, chunks: int, rows: int) -> float:
    """Traced peak of writing --geojson and --gpx for ``chunks`` chunks of ``rows`` rows (the
    chunks made again for the traced run; the event table, which the run keeps anyway,
    made before)."""
    import tracemalloc

    def chunk(k: int) -> tuple[pd.DataFrame, pd.DataFrame]:
        fixes, result = _run(k, n=rows, flagged=0.01)
        fixes["t"] += 1e6 * k  # later chunks later in time, lines go on
        return fixes, result

    builder = EventBuilder()
    for k in range(chunks):
        builder.add(*chunk(k))
    events = builder.events()
    tracemalloc.start()
    try:
        with StreamedExports(tmp_path / "o.geojson", tmp_path / "o.gpx") as exports:
            for k in range(chunks):
                exports.add(*chunk(k))
            exports.finish(events)
        return tracemalloc.get_traced_memory()[1] / 1e6
    finally:
        tracemalloc.stop()


def test_the_exports_memory_does_not_grow_with_the_run(tmp_path: Path) -> None:
    """Issue 18: --geojson/--gpx kept every fix and result of the run; now a run six times
    longer needs about the memory of one chunk (what grows with it: an index entry per
    track and chunk, and some hundred bytes per fault event, 1 % of the fixes here)."""
    short = _export_peak_mb(tmp_path, 2, 2_000)
    long = _export_peak_mb(tmp_path, 12, 2_000)
    assert long < 1.3 * short + 0.5, (short, long)

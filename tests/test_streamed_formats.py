"""GPX and NMEA read chunk by chunk (issue 18, bounded memory): the rows, columns, values
and times of the whole-file readers, and the same ``gradgps detect`` output in both modes."""

from __future__ import annotations

import calendar
import importlib
import math
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd
import pytest
from click.testing import CliRunner
from hypothesis import given, settings
from hypothesis import strategies as st

from _read_counter import count_reads
from _whole_file import detect_whole
from gradgps import InputError
from gradgps._cli import main
from gradgps._io import read as read_module
from gradgps._io.gpx import gpx_tables, read_gpx
from gradgps._io.nmea import Epoch, _Clock, _Offsets, epoch_times, nmea_checksum, read_nmea
from gradgps._io.read import load_table, table_chunks
from gradgps._tracks.track import ColumnMap, Table

# Odd inputs on purpose: the Detector says so (gradgps.InputWarning); what is tested here
# is the answer it gives all the same.
pytestmark = pytest.mark.filterwarnings("ignore::gradgps.InputWarning")


def _sentence(body: str) -> str:
    return f"${body}*{nmea_checksum(body):02X}"


def _point(lat: float, lon: float, time: str, extra: str = "") -> str:
    when = f"<time>{time}</time>" if time else ""
    return f'<trkpt lat="{lat:.6f}" lon="{lon:.6f}">{when}{extra}</trkpt>'


def _gpx(tmp_path: Path) -> Path:
    """Three tracks (two of one name), two segments, points without time, and speed,
    course, hdop, satellites and fix only on points past the first few."""
    start = calendar.timegm((2024, 5, 1, 10, 0, 0))
    parts = ['<?xml version="1.0"?>\n<gpx version="1.1" xmlns="http://www.topografix.com/GPX/1/1">']
    for k, name in enumerate(("drive", "drive", "")):
        parts.append(f"<trk><name>{name}</name>" if name else "<trk>")
        for seg in range(2):
            parts.append("<trkseg>")
            for i in range(9):
                t = start + 3600 * k + 600 * seg + i
                stamp = pd.Timestamp(t, unit="s", tz="UTC").strftime("%Y-%m-%dT%H:%M:%S")
                time = "" if (k, seg, i) == (1, 0, 4) else f"{stamp}.{i * 100:03d}Z"
                extra = ""
                if k == 2 and i > 5:
                    extra = (
                        f"<ele>{500 + i}</ele><speed>{10 + i}</speed><course>{i * 10}</course>"
                        f"<hdop>0.{i}</hdop><sat>{i}</sat><fix>{'none' if i == 8 else '3d'}</fix>"
                    )
                parts.append(_point(48.1 + 1e-4 * (i + 10 * seg), 11.5 + 0.01 * k, time, extra))
            parts.append("</trkseg>")
        parts.append("</trk>")
    parts.append("</gpx>\n")
    path = tmp_path / "tracks.gpx"
    path.write_text("\n".join(parts), encoding="utf-8")
    return path


def _nmea(tmp_path: Path) -> Path:
    """GGA-only epochs before the first date, GGA+RMC pairs, a no-fix epoch, a bad
    checksum, midnight with a stale RMC date, and RMC-only epochs after it."""
    lines = []
    for second in range(86390, 86400 + 20):
        tod = second % 86400
        hms = f"{tod // 3600:02d}{tod // 60 % 60:02d}{tod % 60:02d}.00"
        date = "311219" if second < 86400 + 2 else "010120"  # stale for two epochs
        lat = f"{4807.038 + (second - 86390) * 0.01:.3f}"
        quality = 0 if second == 86395 else 1
        if second >= 86394:
            lines.append(_sentence(f"GPRMC,{hms},A,{lat},N,01131.000,E,022.4,084.4,{date},003.1,W"))
        if second < 86405:
            body = f"GPGGA,{hms},{lat},N,01131.000,E,{quality},08,0.9,545.4,M,46.9,M,,"
            lines.append(_sentence(body))
        if second == 86398:
            lines.append(_sentence("GPGGA,235958.00,4807.038,N,01131.000,E,1,08")[:-2] + "00")
    path = tmp_path / "log.nmea"
    path.write_text("\r\n".join(lines) + "\r\n", encoding="ascii")
    return path


def _joined(path: Path, chunk: int) -> tuple[pd.DataFrame, np.ndarray, list[ColumnMap]]:
    chunks = table_chunks(path, chunk)
    tables = list(chunks)
    assert all(len(t.frame) <= chunk for t in tables)
    assert sum(len(t.frame) for t in tables) == chunks.n_rows
    assert [t.row_offset for t in tables] == list(
        np.cumsum([0, *(len(t.frame) for t in tables[:-1])])
    )
    frame = pd.concat([t.frame for t in tables], ignore_index=True)
    assert tuple(frame.columns) == chunks.header
    times = np.concatenate([np.asarray(t.times) for t in tables])
    return frame, times, [t.columns for t in tables]


@pytest.mark.parametrize("chunk", [1, 2, 7, 1000])
@pytest.mark.parametrize("kind", ["gpx", "nmea"])
def test_chunks_hold_what_the_whole_file_reader_gives(
    tmp_path: Path, kind: str, chunk: int
) -> None:
    path = _gpx(tmp_path) if kind == "gpx" else _nmea(tmp_path)
    whole = load_table(path)
    frame, times, maps = _joined(path, chunk)
    pd.testing.assert_frame_equal(frame, whole.frame)
    assert whole.times is not None
    np.testing.assert_array_equal(times, whole.times)
    assert all(m == whole.columns for m in maps)


def test_the_nmea_fixture_has_what_the_test_is_about(tmp_path: Path) -> None:
    table = read_nmea(_nmea(tmp_path))
    assert table.rejected == 1
    assert int((table.frame["fix_quality"] == 0).sum()) == 1
    assert table.frame["time"].iloc[0] == "2019-12-31T23:59:50Z"  # dated from a later RMC
    assert table.frame["time"].iloc[10] == "2020-01-01T00:00:00Z"  # the stale date advanced
    assert np.isnan(table.frame["alt"].iloc[-1])  # RMC only at the end


def test_gpx_fixture_columns(tmp_path: Path) -> None:
    table = read_gpx(_gpx(tmp_path))
    assert {"speed", "course", "hdop", "satellites", "fix"} <= set(table.frame.columns)
    assert table.frame["track"].unique().tolist() == [
        "drive/0",
        "drive/1",
        "drive #1/0",
        "drive #1/1",
        "2/0",
        "2/1",
    ]


def test_columns_named_by_the_caller_apply_to_every_chunk(tmp_path: Path) -> None:
    path = _gpx(tmp_path)
    given = ColumnMap(speed="")
    whole = load_table(path, columns=given)
    assert {t.columns for t in table_chunks(path, 5, columns=given)} == {whole.columns}


def test_gpx_time_needing_nanoseconds_elsewhere_in_the_file_fails_as_read_whole(
    tmp_path: Path,
) -> None:
    # pandas parses the whole file's times in nanoseconds when one needs them; year 1
    # then does not fit, and the whole-file reader names its line. So must chunks.
    body = "".join(
        [
            _point(48.1, 11.5, "0001-01-01T00:00:00Z"),
            _point(48.1, 11.5001, "2024-05-01T10:00:01Z"),
            _point(48.1, 11.5002, "2024-05-01T10:00:02.123456789Z"),
        ]
    )
    path = tmp_path / "ns.gpx"
    path.write_text(f"<gpx><trk><trkseg>\n{body}\n</trkseg></trk></gpx>", encoding="utf-8")
    with pytest.raises(InputError, match="not ISO-8601") as whole:
        read_gpx(path)
    with pytest.raises(InputError, match="not ISO-8601") as chunked:
        list(table_chunks(path, 1))
    assert str(chunked.value) == str(whole.value)


@pytest.mark.parametrize(
    ("name", "text", "match"),
    [
        ("empty.nmea", "", "empty file"),
        ("junk.nmea", "$GPGSV,1,1,00*79\n", "no usable GGA or RMC"),
        ("wpt.gpx", '<gpx><wpt lat="1" lon="2"/></gpx>', "no track points"),
        ("cut.gpx", "<gpx><trk><trkseg><trkpt lat='1' lon='2'>", "malformed XML"),
        ("bad.gpx", "<gpx><trk><trkseg><trkpt lat='x' lon='2'/></trkseg></trk></gpx>", "not a"),
    ],
)
def test_unusable_files_fail_before_the_first_chunk(
    tmp_path: Path, name: str, text: str, match: str
) -> None:
    path = tmp_path / name
    path.write_text(text, encoding="utf-8")
    with pytest.raises(InputError, match=match):
        table_chunks(path, 2)


def _epochs(tod: list[float], midnight: list[float]) -> list[Epoch]:
    return [
        Epoch(line=i, tod=a, midnight=b) for i, (a, b) in enumerate(zip(tod, midnight, strict=True))
    ]


_DAY = 86400.0


@settings(max_examples=300, deadline=None)
@given(
    st.lists(
        st.tuples(
            st.sampled_from([0.0, 1.0, 30.0, 599.0, 601.0, 3600.0, 43000.0, 86399.0, math.nan]),
            st.sampled_from([math.nan, math.nan, 1e9 - 1e9 % _DAY, 1e9 - 1e9 % _DAY + _DAY]),
        ),
        min_size=1,
        max_size=12,
    ),
    st.integers(1, 4),
)
def test_streamed_clock_is_epoch_times(pairs: list[tuple[float, float]], chunk: int) -> None:
    tod = [p[0] for p in pairs]
    midnight = [p[1] for p in pairs]
    epochs = _epochs(tod, midnight)
    offsets = _Offsets()
    for k in range(0, len(epochs), chunk):
        offsets.add(epochs[k : k + chunk])
    offsets.finish()
    clock = _Clock(offsets)
    got = np.concatenate([clock.times(epochs[k : k + chunk]) for k in range(0, len(epochs), chunk)])
    np.testing.assert_array_equal(got, epoch_times(np.array(tod), np.array(midnight)))


def _detect(args: list[str]) -> str:
    result = CliRunner().invoke(main, ["detect", *args])
    assert result.exit_code == 0, result.output
    return str(result.output)


@pytest.mark.parametrize("kind", ["gpx", "nmea"])
def test_detect_gives_the_same_output_chunked_and_whole(tmp_path: Path, kind: str) -> None:
    """Chunks of 3 rows give the output, events and counts of detection on the file read
    whole (the library's, :func:`detect_whole`: ``--chunk-size 0`` reads in chunks too)."""
    path = _gpx(tmp_path) if kind == "gpx" else _nmea(tmp_path)
    out, events = tmp_path / "out.csv", tmp_path / "events.csv"
    text = _detect([str(path), "-o", str(out), "--events", str(events), "--chunk-size", "3"])
    wrote = next(s for s in text.splitlines() if s.startswith("wrote")).split(": ", 1)[1]
    whole, whole_events = tmp_path / "whole.csv", tmp_path / "whole_events.csv"
    counts = detect_whole(path, whole, events=whole_events)
    assert out.read_bytes() == whole.read_bytes()
    assert events.read_bytes() == whole_events.read_bytes()
    # The summary line, throughput aside.
    assert wrote.rsplit(";", 1)[0] == counts


@pytest.mark.parametrize("kind", ["gpx", "nmea"])
def test_detect_streams_gpx_and_nmea_without_reading_them_whole(
    tmp_path: Path, kind: str, monkeypatch: pytest.MonkeyPatch
) -> None:
    path = _gpx(tmp_path) if kind == "gpx" else _nmea(tmp_path)

    def whole(*_: object, **__: object) -> None:
        raise AssertionError("read whole")

    monkeypatch.setattr(read_module, f"read_{kind}", whole)
    out = tmp_path / "out.csv"
    _detect([str(path), "-o", str(out), "--chunk-size", "4"])
    assert len(pd.read_csv(out)) == len(_joined(path, 4)[0])


def test_chunk_size_0_reads_in_the_largest_bounded_chunks_not_the_whole_file(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Issue 18: ``--chunk-size 0`` read the whole file (about 10 GB for a 1 GB CSV) for
    outputs byte for byte those of the chunks. It now asks for the largest chunks the
    memory bound allows (here made 4 rows, to see them): the file is never read whole, no
    warning says it is, and the output is the whole-file detection's."""
    path = _gpx(tmp_path)
    monkeypatch.setattr(read_module, "MAX_CHUNK_ROWS", 4, raising=False)  # new in issue 18
    chunked_module = importlib.import_module("gradgps._run.chunked")
    sizes: list[int] = []

    def counted(*args: Any, **kwargs: Any) -> read_module.CsvChunks:
        found = table_chunks(*args, **kwargs)

        def each() -> Iterator[Table]:
            for table in found:
                sizes.append(len(table.frame))
                yield table

        return read_module.CsvChunks(found.n_rows, found.header, each())

    def whole(*_: object, **__: object) -> None:
        raise AssertionError("read whole")

    monkeypatch.setattr(chunked_module, "table_chunks", counted)
    monkeypatch.setattr(read_module, "load_table", whole)
    out = tmp_path / "out.csv"
    text = _detect([str(path), "-o", str(out), "--chunk-size", "0"])
    assert "read whole" not in text
    assert "memory grows" not in text
    assert sizes == [4] * 13 + [2]
    monkeypatch.undo()
    reference = tmp_path / "whole.csv"
    detect_whole(path, reference)
    assert out.read_bytes() == reference.read_bytes()


def _traced_peak_mb(read: object) -> float:
    import tracemalloc

    tracemalloc.start()
    try:
        read()  # type: ignore[operator]
        return tracemalloc.get_traced_memory()[1] / 1e6
    finally:
        tracemalloc.stop()


def test_an_nmea_log_without_line_breaks_is_read_in_pieces_with_the_same_epochs(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    lines = _nmea(tmp_path).read_text(encoding="ascii").splitlines()
    path = tmp_path / "one_line.nmea"
    path.write_text("junk before" + "".join(lines), encoding="ascii")  # no line breaks at all
    whole = read_nmea(path)
    assert len(whole.frame) == 30
    monkeypatch.setattr("gradgps._io.nmea._PIECE_BYTES", 37)
    pieces = read_nmea(path)
    pd.testing.assert_frame_equal(pieces.frame, whole.frame)
    assert (pieces.rejected, pieces.notes) == (whole.rejected, whole.notes)
    assert len(table_chunks(path, 4).chunks.__next__().frame) == 4


def test_a_huge_nmea_line_or_gpx_text_is_never_held_whole(tmp_path: Path) -> None:
    good = _nmea(tmp_path).read_text(encoding="ascii")
    nmea = tmp_path / "huge_line.nmea"
    nmea.write_text("x" * 30_000_000 + "\r\n" + good, encoding="ascii")
    assert _traced_peak_mb(lambda: read_nmea(nmea)) < 10
    assert len(read_nmea(nmea).frame) == 30
    gpx = tmp_path / "huge_desc.gpx"
    desc = "<metadata><desc>" + "d" * 30_000_000 + "</desc></metadata>"
    gpx.write_text(
        f"<gpx>{desc}<trk><trkseg>{_point(48.1, 11.5, '2024-05-01T10:00:00Z')}"
        "</trkseg></trk></gpx>",
        encoding="utf-8",
    )
    assert _traced_peak_mb(lambda: read_gpx(gpx)) < 10
    assert len(read_gpx(gpx).frame) == 1


def test_a_gpx_name_or_value_longer_than_1_mib_is_an_error(tmp_path: Path) -> None:
    for where in (
        "<name>{}</name>",
        "<trkseg><trkpt lat='1' lon='2'><ele>{}</ele></trkpt></trkseg>",
    ):
        path = tmp_path / "long.gpx"
        path.write_text(f"<gpx><trk>{where.format('7' * 1_100_000)}</trk></gpx>", encoding="utf-8")
        with pytest.raises(InputError, match="holds more than 1,048,576 characters"):
            read_gpx(path)


@pytest.mark.parametrize(
    "markup",
    ["<trk{} lat='1'/>", "<trk a{}='1'/>", "<!--{}-->", "<?pi {}?>"],
    ids=["tag name", "attribute name", "comment", "processing instruction"],
)
def test_gpx_markup_longer_than_1_mib_is_an_error_read_in_bounded_memory(
    tmp_path: Path, markup: str, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Issue 18: expat holds a token (a tag, an attribute, a comment) whole until it ends,
    in its own C buffer, so a tag name of gigabytes was held whole, whole-file or chunked.
    Now more than 1 MiB of markup unparsed is an error naming its line, raised after about
    that much of the file is read (counted at the file object: expat's buffer is not
    Python's, so tracemalloc cannot see it)."""
    import gradgps._io.gpx as gpx_module

    path = tmp_path / "long_markup.gpx"
    path.write_text(
        f"<gpx><trk><trkseg>{_point(48.1, 11.5, '2024-05-01T10:00:00Z')}</trkseg></trk>\n"
        + markup.format("x" * 20_000_000)
        + "</gpx>",
        encoding="utf-8",
    )
    read_bytes = count_reads(monkeypatch, gpx_module)
    for read in (lambda: read_gpx(path), lambda: list(gpx_tables(path, 3).chunks)):
        read_bytes.clear()
        with pytest.raises(InputError, match="markup longer than 1,048,576 bytes") as caught:
            read()
        assert caught.value.line == 2
        assert 0 < sum(read_bytes) < 2 << 20


def test_parquet_chunks_do_not_read_ahead_the_whole_file(tmp_path: Path) -> None:
    """Issue 18: pyarrow's pre-buffering read ahead the column chunks of every row group
    still to come and held them (the peak of a chunked Parquet run grew with the file: 555
    MB at 1.56 M fixes, 619 at 4.69 M). Arrow's memory pool counts what it held; a fresh
    process reads a 9.6 MB file of 20 row groups in chunks of 5,000 rows."""
    import subprocess
    import sys

    pytest.importorskip("pyarrow")
    path = tmp_path / "groups.parquet"
    n = 400_000
    rng = np.random.default_rng(0)
    frame = pd.DataFrame(
        {"t": np.arange(n, dtype=float), "lat": rng.random(n), "lon": rng.random(n)}
    )
    frame.to_parquet(path, row_group_size=20_000)
    script = (
        "import sys, pyarrow as pa\n"
        "from gradgps._io.read import table_chunks\n"
        "rows = sum(len(t.frame) for t in table_chunks(sys.argv[1], 5_000))\n"
        "print(rows, pa.default_memory_pool().max_memory())\n"
    )
    done = subprocess.run(
        [sys.executable, "-c", script, str(path)], capture_output=True, text=True, check=True
    )
    rows, peak = (int(v) for v in done.stdout.split())
    assert rows == n
    assert peak < 0.3 * path.stat().st_size, (peak, path.stat().st_size)


def _track_file(tmp_path: Path, kind: str) -> Path:
    """A small file of ``kind`` (every format ``table_chunks`` reads in chunks)."""
    if kind == "gpx":
        return _gpx(tmp_path)
    if kind == "nmea":
        return _nmea(tmp_path)
    if kind == "rosbag":
        pytest.importorskip("rosbags")
        from rosbags.rosbag2 import StoragePlugin
        from rosbags.rosbag2 import Writer as Writer2
        from rosbags.typesys import Stores, get_typestore

        from _rosbag_support import write_drive

        store = get_typestore(Stores.ROS2_HUMBLE)
        path = tmp_path / "bag"
        with Writer2(path, version=9, storage_plugin=StoragePlugin.MCAP) as writer:
            write_drive(writer, store, store.serialize_cdr, extra_topic=True)
        return path
    n = 40
    frame = pd.DataFrame(
        {
            "track": np.tile(["a", "b"], n // 2),
            "t": 1.7e9 + np.repeat(np.arange(n // 2, dtype=float), 2),
            "lat": 48.1 + 1e-5 * np.arange(n),
            "lon": 11.5,
            "note": "x",
        }
    )
    if kind == "csv":
        path = tmp_path / "fixes.csv"
        frame.to_csv(path, index=False)
        return path
    if kind == "geojson":  # Point features whose properties make 30 columns
        import json

        props = {f"p{k}": k for k in range(26)}
        features = [
            {
                "type": "Feature",
                "geometry": {"type": "Point", "coordinates": [r.lon, r.lat]},
                "properties": {"track": r.track, "time": r.t, **props},
            }
            for r in frame.itertuples()
        ]
        path = tmp_path / "fixes.geojson"
        path.write_text(json.dumps({"type": "FeatureCollection", "features": features}))
        return path
    pytest.importorskip("pyarrow")
    path = tmp_path / "fixes.parquet"
    if kind == "parquet":
        frame.to_parquet(path, index=False)
        return path
    gpd = pytest.importorskip("geopandas")
    points = gpd.points_from_xy(frame.pop("lon"), frame.pop("lat"))
    gpd.GeoDataFrame(frame, geometry=points, crs="EPSG:4326").to_parquet(path)
    return path


@pytest.mark.parametrize(
    "kind", ["csv", "parquet", "geoparquet", "gpx", "nmea", "geojson", "rosbag"]
)
def test_every_chunked_format_holds_a_huge_chunk_size_to_the_memory_bound(
    tmp_path: Path, kind: str, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Issue 18: ``--chunk-size 100000000`` (or 0, the largest) must not hold the file in
    any format. A chunk has at most ``MAX_CHUNK_ROWS`` rows and ``MAX_CHUNK_CELLS`` cells
    (made 9 rows and 36 cells here to see them) whatever is asked; only the CSV reader
    cut its chunks by cells before, Parquet, GPX, NMEA and ROS bags took the chunk size
    as given. GPX, NMEA and bags cut by their widest row, whose width is checked too;
    GeoJSON, as wide as its properties (30 columns here), by the width its first pass finds."""
    path = _track_file(tmp_path, kind)
    rows = len(load_table(path).frame)
    for most_rows, most_cells in ((9, 10**6), (10**6, 36)):
        monkeypatch.setattr(read_module, "MAX_CHUNK_ROWS", most_rows, raising=False)
        monkeypatch.setattr(read_module, "MAX_CHUNK_CELLS", most_cells)
        chunks = list(table_chunks(path, 100_000_000))
        assert sum(len(c.frame) for c in chunks) == rows
        assert len(chunks) > 1
        for chunk in chunks:
            assert len(chunk.frame) <= most_rows
            assert len(chunk.frame) * len(chunk.frame.columns) <= most_cells
            if kind != "geojson":
                assert len(chunk.frame.columns) <= read_module.STREAMED_WIDEST_ROW


@pytest.mark.parametrize("command", ["detect", "detect-fleet"])
def test_the_chunk_size_help_names_the_bound_the_readers_apply(command: str) -> None:
    """The help quotes the bound as numbers (the CLI does not import the readers to build
    it): they must be the readers' own."""
    text = " ".join(CliRunner().invoke(main, [command, "--help"]).output.split())
    bound = f"{read_module.MAX_CHUNK_ROWS:,} rows and {read_module.MAX_CHUNK_CELLS:,} cells"
    assert bound in text

"""GeoJSON read streaming and in chunks (issue 18, bounded memory): the rows, columns,
values and dtypes of the whole-file reader, what :func:`json.loads` gave it before, the
same ``gradgps detect`` output in every mode, and memory that does not grow with the file."""

from __future__ import annotations

import gzip
import io
import json
import tracemalloc
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pandas as pd
import pytest
from click.testing import CliRunner
from hypothesis import given, settings
from hypothesis import strategies as st

from _read_counter import count_reads
from gradgps import InputError
from gradgps._cli import main
from gradgps._io import geojson_rows
from gradgps._io import read as read_module
from gradgps._io.geojson import read_geojson
from gradgps._io.read import load_table, table_chunks


def _point(i: int, **props: Any) -> dict[str, Any]:
    coords = [11.5 + i * 1e-4, 48.1 + i * 1e-5] + ([500.0 + i] if i % 3 == 0 else [])
    return {
        "type": "Feature",
        "geometry": {"type": "Point", "coordinates": coords},
        "properties": props,
    }


def _points_doc() -> dict[str, Any]:
    """Properties that vary along the file: a speed whole at first and a fraction later, a
    null and a gap, nested values, a column named only by the last features, a ``lat``
    property (not a column), a null feature, a polygon and an empty Point."""
    features: list[Any] = []
    for i in range(23):
        props: dict[str, Any] = {"time": f"2024-05-01T10:00:{i:02d}Z", "track": "a"}
        if i != 5:
            props["speed"] = i if i < 15 else i + 0.5
        if i == 7:
            props["speed"] = None
        if i % 4 == 1:
            props["extra"] = {"hdop": [0.9, i], "ok": True, "name": "é"}
        if i == 2:
            props["lat"] = 99.0
        if i > 18:
            props["late"] = i % 2 == 0
        features.append(_point(i, **props))
    features.insert(3, None)
    features.insert(9, {"type": "Feature", "geometry": {"type": "Polygon", "coordinates": []}})
    features.insert(12, {"type": "Feature", "geometry": {"type": "Point", "coordinates": []}})
    return {"type": "FeatureCollection", "name": "fixes", "features": features}


def _lines_doc() -> dict[str, Any]:
    """A LineString with coordTimes (properties first), a MultiLineString with an array of
    arrays of times (geometry first, keys sorted, as python-geojson writes), one with
    fewer times than vertices and no name, and a Point between them."""
    times = [f"2024-05-01T11:00:{i:02d}Z" for i in range(9)]
    line = {
        "type": "Feature",
        "properties": {"name": "drive", "coordTimes": times, "times": [1, 2]},
        "geometry": {
            "type": "LineString",
            "coordinates": [[11.5 + i * 1e-4, 48.1, 500 + i] for i in range(9)],
        },
    }
    multi = {
        "geometry": {
            "coordinates": [
                [[11.6 + i * 1e-4, 48.2] for i in range(4)],
                [[11.7 + i * 1e-4, 48.3, 400.5] for i in range(5)],
            ],
            "type": "MultiLineString",
        },
        "properties": {"coordTimes": [times[:4], times[4:]], "name": 7},
        "type": "Feature",
    }
    short = {
        "type": "Feature",
        "geometry": {"type": "LineString", "coordinates": [[11.8, 48.4], [11.8001, 48.4]] * 3},
        "properties": {"timestamps": ["2024-05-01T12:00:00Z", "2024-05-01T12:00:01Z"]},
    }
    return {
        "features": [line, _point(1, time=times[0]), multi, short],
        "type": "FeatureCollection",
    }


def _single_doc() -> dict[str, Any]:
    """A single Feature, its ``type`` after its geometry."""
    doc = _lines_doc()["features"][0]
    return {"geometry": doc["geometry"], "properties": doc["properties"], "type": "Feature"}


_DOCS = {"points": _points_doc, "lines": _lines_doc, "single": _single_doc}


def _write(tmp_path: Path, name: str, how: str = "plain") -> Path:
    text = json.dumps(_DOCS[name]())
    if how == "gzip":
        path = tmp_path / f"{name}.geojson.gz"
        path.write_bytes(gzip.compress(text.encode()))
    elif how == "bom":
        path = tmp_path / f"{name}.geojson"
        path.write_bytes(b"\xef\xbb\xbf" + text.encode())
    else:
        path = tmp_path / f"{name}.json"
        path.write_text(text, encoding="utf-8")
    return path


def _json_loads_rows(doc: dict[str, Any]) -> list[dict[str, Any]]:
    """The rows the reader made from :func:`json.loads` before it streamed (its code)."""

    def flat(props: dict[str, Any]) -> dict[str, Any]:
        return {
            str(k): (json.dumps(v) if isinstance(v, dict | list) else v)
            for k, v in props.items()
            if str(k) not in ("lat", "lon", "alt")
        }

    def position(c: list[Any]) -> dict[str, Any]:
        return {"lon": c[0], "lat": c[1], **({"alt": c[2]} if len(c) > 2 else {})}

    features = [doc] if doc["type"] == "Feature" else doc["features"]
    rows: list[dict[str, Any]] = []
    for k, feature in enumerate(features):
        geometry = (feature or {}).get("geometry") or {}
        props = dict((feature or {}).get("properties") or {})
        kind, coords = geometry.get("type"), geometry.get("coordinates")
        if kind == "Point" and coords:
            rows.append({**flat(props), **position(coords)})
        elif kind in ("LineString", "MultiLineString") and coords:
            lines = [coords] if kind == "LineString" else coords
            times = next(
                (props[n] for n in geojson_rows.TIME_ARRAYS if isinstance(props.get(n), list)),
                None,
            )
            if kind == "MultiLineString" and times and isinstance(times[0], list):
                times = [t for part in times for t in part]
            for i, c in enumerate(c for line in lines for c in line):
                row = {"track": str(props.get("name", k)), **position(c)}
                row["time"] = times[i] if times is not None and i < len(times) else None
                rows.append(row)
    return rows


@pytest.mark.parametrize("name", sorted(_DOCS))
def test_whole_file_rows_are_what_json_loads_gave(tmp_path: Path, name: str) -> None:
    table = read_geojson(_write(tmp_path, name))
    expected = pd.DataFrame(_json_loads_rows(_DOCS[name]()))
    pd.testing.assert_frame_equal(table.frame, expected)
    assert table.columns.alt == "alt"


def test_the_fixtures_have_what_the_tests_are_about(tmp_path: Path) -> None:
    frame = read_geojson(_write(tmp_path, "points")).frame
    assert list(frame.columns) == ["time", "track", "speed", "lon", "lat", "alt", "extra", "late"]
    assert frame["speed"].dtype == "float64"
    assert frame["late"].dtype == object
    assert frame["extra"].iloc[1] == '{"hdop": [0.9, 1], "ok": true, "name": "\\u00e9"}'
    lines = read_geojson(_write(tmp_path, "lines")).frame
    assert lines["track"].dropna().unique().tolist() == ["drive", "7", "3"]
    assert pd.isna(lines["time"].iloc[-1])
    assert lines["time"].iloc[-6] == "2024-05-01T12:00:00Z"


def _with_budget(budget: int | None, monkeypatch: pytest.MonkeyPatch) -> None:
    if budget is not None:
        monkeypatch.setattr(geojson_rows, "FEATURE_EVENTS", budget)


@pytest.mark.parametrize("budget", [None, 0, 1, 7])
@pytest.mark.parametrize("chunk", [1, 2, 7, 1000])
@pytest.mark.parametrize(
    ("name", "how"),
    [
        ("points", "plain"),
        ("lines", "plain"),
        ("single", "plain"),
        ("lines", "gzip"),
        ("points", "bom"),
    ],
)
def test_chunks_hold_what_the_whole_file_reader_gives(
    tmp_path: Path,
    monkeypatch: pytest.MonkeyPatch,
    name: str,
    how: str,
    chunk: int,
    budget: int | None,
) -> None:
    """``budget``: the parse events of a feature built in memory (0: every container is
    streamed by a cursor of its own; ``None``: as shipped)."""
    path = _write(tmp_path, name, how)
    whole = load_table(path)
    _with_budget(budget, monkeypatch)
    pd.testing.assert_frame_equal(read_geojson(path).frame, whole.frame)
    chunks = table_chunks(path, chunk)
    tables = list(chunks)
    assert all(0 < len(t.frame) <= chunk for t in tables)
    assert [t.row_offset for t in tables] == list(range(0, len(whole.frame), chunk))
    assert chunks.n_rows == len(whole.frame)
    assert chunks.header == tuple(whole.frame.columns)
    assert {t.columns for t in tables} == {whole.columns}
    frame = pd.concat([t.frame for t in tables], ignore_index=True)
    pd.testing.assert_frame_equal(frame, whole.frame)


def test_a_chunk_is_typed_as_the_whole_file_not_by_its_own_rows(tmp_path: Path) -> None:
    # A chunk of whole speeds is float where the file has a gap; of true/false, objects
    # where the file has a gap; of words, text where others are numbers.
    features = [_point(0, speed=1, flag=True, label="x"), _point(1, speed=2, flag=False, label=3)]
    features.append(_point(2, label=None))
    path = tmp_path / "kinds.geojson"
    path.write_text(json.dumps({"type": "FeatureCollection", "features": features}))
    whole = read_geojson(path).frame
    first = next(iter(table_chunks(path, 1))).frame
    assert dict(first.dtypes) == dict(whole.dtypes)
    assert first["speed"].iloc[0] == 1.0
    assert first["label"].iloc[0] == "x"
    assert whole["flag"].dtype == object
    assert whole["label"].dtype == object


def _errors(path: Path) -> tuple[str, str]:
    with pytest.raises(InputError) as whole:
        read_geojson(path)
    with pytest.raises(InputError) as chunked:
        table_chunks(path, 2)  # the first pass: before any chunk
    return str(whole.value), str(chunked.value)


@pytest.mark.parametrize(
    ("text", "match"),
    [
        ("", "not valid GeoJSON: parse error: premature EOF"),
        ('{"type": "FeatureCollection", "features": [{"type": "Feature",', "premature EOF"),
        ('{"type": "FeatureCollection", "features": []} x', "trailing garbage near"),
        ('{"type": "FeatureCollection", "features": [NaN]}', r"\(in feature 0\)|invalid char"),
        ("[1, 2]", "not a GeoJSON FeatureCollection or Feature"),
        ('{"type": "Topology", "features": []}', "not a GeoJSON FeatureCollection or Feature"),
        ('{"type": "FeatureCollection", "features": []}', "no Point or LineString features"),
        ('{"type": "FeatureCollection"}', "no Point or LineString features"),
        ('{"type": "FeatureCollection", "features": {}}', "'features' is not an array"),
        ('{"type": "FeatureCollection", "features": [3]}', "feature 0 is not an object"),
        ('{"features": [], "type": "FeatureCollection", "type": "x"}', "the key 'type' twice"),
        (
            '{"type": "Feature", "geometry": {"type": "Point", "coordinates": [1]}}',
            r"feature 0 \(Point\): the coordinates are not a position",
        ),
        (
            '{"type": "Feature", "geometry": {"type": "LineString", '
            '"coordinates": [[1, 2], [3, [4]]]}}',
            r"feature 0 \(LineString\): vertex 1 is not a position",
        ),
        (
            '{"type": "FeatureCollection", "features": [{"geometry": null, "geometry": {}}]}',
            "feature 0 has the key 'geometry' twice",
        ),
        (
            '{"type": "FeatureCollection", "features": [{"properties": [1]}]}',
            "feature 0: 'properties' is not an object",
        ),
    ],
)
def test_unusable_files_fail_alike_whole_and_in_chunks(
    tmp_path: Path, text: str, match: str
) -> None:
    path = tmp_path / "bad.geojson"
    path.write_text(text, encoding="utf-8")
    whole, chunked = _errors(path)
    assert whole == chunked
    assert whole.startswith(str(path) + ": ")
    assert "\n" not in whole
    with pytest.raises(InputError, match=match):
        read_geojson(path)


def test_damaged_gzip_and_non_utf8_are_input_errors(tmp_path: Path) -> None:
    good = _write(tmp_path, "points", "gzip")
    cut = tmp_path / "cut.geojson.gz"
    cut.write_bytes(good.read_bytes()[:-30])
    assert "cannot read" in _errors(cut)[0] or "premature EOF" in _errors(cut)[0]
    latin = tmp_path / "latin.geojson"
    latin.write_bytes(b'{"type": "Feature", "properties": {"name": "\xe9"}}')
    assert "invalid bytes in UTF8 string" in _errors(latin)[0]


def _detect(args: list[str]) -> str:
    result = CliRunner().invoke(main, ["detect", *args])
    assert result.exit_code == 0, result.output
    return str(result.output)


def _outputs(tmp_path: Path, path: Path, chunk: str, tag: str) -> tuple[bytes, bytes, str]:
    out, events = tmp_path / f"out{tag}.csv", tmp_path / f"events{tag}.csv"
    text = _detect([str(path), "-o", str(out), "--events", str(events), "--chunk-size", chunk])
    wrote = next(s for s in text.splitlines() if s.startswith("wrote")).split(": ", 1)[1]
    return out.read_bytes(), events.read_bytes(), wrote.rsplit(";", 1)[0]  # throughput aside


@pytest.mark.parametrize("name", ["points", "lines"])
def test_detect_gives_the_same_output_chunked_whole_and_from_csv(tmp_path: Path, name: str) -> None:
    path = _write(tmp_path, name)
    chunked = _outputs(tmp_path, path, "3", "chunked")
    assert chunked == _outputs(tmp_path, path, "0", "whole")
    csv = tmp_path / f"{name}.csv"
    read_geojson(path).frame.to_csv(csv, index=False)
    assert chunked == _outputs(tmp_path, csv, "3", "csv")


def test_detect_streams_geojson_without_reading_it_whole(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    path = _write(tmp_path, "lines")

    def whole(*_: object, **__: object) -> None:
        raise AssertionError("read whole")

    monkeypatch.setattr(read_module, "read_geojson", whole)
    out = tmp_path / "out.csv"
    _detect([str(path), "-o", str(out), "--chunk-size", "4", "--report", str(tmp_path / "r.html")])
    assert len(pd.read_csv(out)) == table_chunks(path, 4).n_rows


# --- memory -----------------------------------------------------------------------------


def _points_file(path: Path, n: int) -> Path:
    with path.open("w") as out:
        out.write('{"type": "FeatureCollection", "features": [')
        for i in range(n):
            out.write(
                ("," if i else "")
                + json.dumps(_point(i, time=f"2024-05-01T10:00:00.{i:06d}Z", track=f"t{i // 500}"))
            )
        out.write("]}")
    return path


def _line_file(path: Path, n: int, geometry_first: bool) -> Path:
    """One track as one LineString of ``n`` vertices and its coordTimes, written as a
    logger would, piece by piece."""
    coords = "[" + ",".join(f"[{11.5 + i * 1e-6:.7f},{48.1:.1f},{500 + i}]" for i in range(n)) + "]"
    times = json.dumps([f"2024-05-01T10:00:00.{i:06d}Z" for i in range(n)])
    geometry = f'"geometry": {{"type": "LineString", "coordinates": {coords}}}'
    props = f'"properties": {{"name": "drive", "coordTimes": {times}}}'
    parts = [geometry, props] if geometry_first else [props, geometry]
    path.write_text('{"type": "Feature", ' + ", ".join(parts) + "}")
    return path


def _peak_mb(path: Path, chunk: int) -> float:
    """Peak of Python's allocations while reading ``path`` in chunks, each dropped."""

    def rows(tables: Iterator[Any]) -> int:
        return sum(len(t.frame) for t in tables)

    tracemalloc.start()
    try:
        chunks = table_chunks(path, chunk)
        assert rows(chunks.chunks) == chunks.n_rows
        return tracemalloc.get_traced_memory()[1] / 1e6
    finally:
        tracemalloc.stop()


@pytest.mark.parametrize("shape", ["points", "line, properties first", "line, geometry first"])
def test_memory_of_chunks_does_not_grow_with_the_file(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, shape: str
) -> None:
    """Issue 18: GeoJSON was read whole (json.loads), 9.1 MB of memory per MB of file.
    Read in chunks of 500 rows, a file of four times the fixes needs the same memory,
    a track as one LineString with its coordTimes included: beyond the events of a
    feature built in memory (2,000 here, so that small files show it), its arrays are
    streamed."""
    monkeypatch.setattr(geojson_rows, "FEATURE_EVENTS", 2_000)
    peaks = []
    for n in (5_000, 20_000):
        path = tmp_path / f"{n}.geojson"
        if shape == "points":
            _points_file(path, n)
        else:
            _line_file(path, n, geometry_first=shape.endswith("geometry first"))
        peaks.append(_peak_mb(path, 500))
    small, big = peaks
    assert big < 1.2 * small + 0.5, peaks


def test_a_big_lat_property_of_a_point_is_skipped_like_a_small_one(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    # Found by make fuzz: with every container streamed, a Point's big ``lat`` property
    # (not a column) was looked up among the big values fetched for it (KeyError).
    path = tmp_path / "lat.geojson"
    feature = _point(0, t=["2024-05-01T10:00:00Z"] * 6, lat=[], time=None)
    path.write_text(json.dumps(feature))
    whole = read_geojson(path).frame
    monkeypatch.setattr(geojson_rows, "FEATURE_EVENTS", 0)
    pd.testing.assert_frame_equal(read_geojson(path).frame, whole)
    assert list(whole.columns) == ["t", "time", "lon", "lat", "alt"]


_JSON_BYTES = st.recursive(
    st.none()
    | st.booleans()
    | st.integers(-(10**15), 10**15)
    | st.floats(allow_nan=False, allow_infinity=False)
    | st.text(alphabet='ab"\\{}[],: \n\té', max_size=40),
    lambda inner: (
        st.lists(inner, max_size=4)
        | st.dictionaries(st.text(alphabet='k"\\ :', max_size=6), inner, max_size=4)
    ),
    max_leaves=12,
).map(lambda value: json.dumps(value, ensure_ascii=False).encode("utf-8"))


@settings(max_examples=300, deadline=None)
@given(data=_JSON_BYTES, block=st.integers(1, 70))
def test_the_scalar_bound_agrees_with_its_readable_reference(data: bytes, block: int) -> None:
    """The vectorised scanner carried across blocks of any size finds the longest string
    or scalar that the byte-by-byte reference finds (escaped quotes, runs of backslashes
    split across blocks, separators inside strings)."""
    from gradgps._io.json_events import _ScalarBound, longest_scalar

    longest = longest_scalar(data)
    for limit, refused in ((longest, False), (longest - 1, True)):
        if limit < 0:
            continue
        bound = _ScalarBound(io.BytesIO(data), "doc.json", limit=limit)
        try:
            while bound.read(block):
                pass
        except InputError:
            assert refused, (limit, longest)
        else:
            assert not refused, (limit, longest)


@pytest.mark.parametrize(
    "scalar",
    ['"' + "x" * 20_000_000 + '"', "1" * 20_000_000, '"' + 'a\\"' * 7_000_000 + '"'],
    ids=["string", "number", "string of escaped quotes"],
)
def test_a_string_or_number_longer_than_1_mib_is_an_error_before_it_is_held(
    tmp_path: Path, scalar: str, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Issue 18 round three: the parser holds a token whole until it ends (in its own C
    buffer, which tracemalloc does not see), so one string or number of gigabytes in a
    GeoJSON property was held whole, whole-file or chunked. Now it is an error naming the
    file once about 1 MiB of it is read (counted at the file objects)."""
    from gradgps._io import json_events

    read_bytes = count_reads(monkeypatch, json_events)
    point = '{"type": "Feature", "geometry": {"type": "Point", "coordinates": [11.5, 48.1]}'
    path = tmp_path / "long_scalar.geojson"
    path.write_text(
        '{"type": "FeatureCollection", "features": ['
        + point
        + ', "properties": {"time": 1}}, '
        + point
        + ', "properties": {"note": '
        + scalar
        + "}}]}",
        encoding="utf-8",
    )
    for read in (lambda: read_geojson(path), lambda: list(table_chunks(path, 1))):
        read_bytes.clear()
        with pytest.raises(InputError, match="longer than 1,048,576 bytes") as caught:
            read()
        assert "long_scalar.geojson" in str(caught.value)
        assert 0 < sum(read_bytes) < 2 << 20

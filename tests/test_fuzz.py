"""Fuzzing: hostile tracks and file bytes may only ever raise gradgps's own errors.

Every case goes through the whole path a user's file takes: read (CSV,
GPX, NMEA), convert to fixes, batch detection, streaming detection and, for
CSV, chunked detection to a file. The only exceptions allowed are
:class:`gradgps.GradGPSError` subclasses, whose messages name the problem;
anything else (a ``KeyError`` from deep inside pandas, a warning, which
pytest turns into an error) is a bug. When no error is raised, every input
row must come back as exactly one result row.

``make test`` runs a few dozen cases per test; ``make fuzz`` sets
``GRADGPS_FUZZ_EXAMPLES`` (2,500 per test, 15,000 in all).
"""

from __future__ import annotations

import os
from collections.abc import Callable
from pathlib import Path
from typing import TypeVar

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from _track_strategies import expected_reasons, messy_tracks
from gradgps import GradGPSError, iter_csv_tables, read_table, to_fixes
from gradgps._grad.detector import Detector, MultiTrackDetector
from gradgps._io.nmea import nmea_checksum
from gradgps._run.chunked import detect_csv_in_chunks

T = TypeVar("T")
EXAMPLES = int(os.environ.get("GRADGPS_FUZZ_EXAMPLES", "30"))
fuzz = settings(
    max_examples=EXAMPLES,
    deadline=None,
    suppress_health_check=[
        HealthCheck.too_slow,
        HealthCheck.data_too_large,
        HealthCheck.function_scoped_fixture,
    ],
)

# --- byte strategies -----------------------------------------------------------


def _mutated(document: st.SearchStrategy[bytes]) -> st.SearchStrategy[bytes]:
    """A well-formed-ish document, sometimes cut off or with random bytes spliced in."""

    @st.composite
    def build(draw: st.DrawFn) -> bytes:
        data = draw(document)
        how = draw(st.sampled_from(["keep", "keep", "truncate", "splice", "flip"]))
        if how == "keep" or not data:
            return data
        at = draw(st.integers(0, len(data)))
        if how == "truncate":
            return data[:at]
        if how == "splice":
            return data[:at] + draw(st.binary(max_size=8)) + data[at:]
        at = min(at, len(data) - 1)
        return data[:at] + bytes([data[at] ^ draw(st.integers(1, 255))]) + data[at + 1 :]

    return st.one_of(build(), st.binary(max_size=200))


_NUMBERS = st.one_of(
    st.floats(allow_nan=True, allow_infinity=True).map(repr),
    st.integers(-(10**20), 10**20).map(str),
    st.sampled_from(
        [
            "",
            "nan",
            "NaN",
            "inf",
            "-inf",
            "Infinity",
            "-0",
            "1e308",
            "-1e309",
            "41.25",
            "-95.98",
            "1700000000",
            "1700000000000",
            "NA",
            "null",
        ]
    ),
)
_JUNK = st.sampled_from(
    [
        "abc",
        '"',
        '""',
        "a,b",
        "é",
        " ",
        "\t",
        "2024-01-01T00:00:00Z",
        "2024-13-45T99:99:99",
        "12:00",
        "true",
        "0x10",
        "1_000",
        "--1",
    ]
)
_CELL = st.one_of(_NUMBERS, _NUMBERS, _JUNK)
_COLUMN = st.sampled_from(
    [
        "t",
        "time",
        "timestamp",
        "lat",
        "latitude",
        "lon",
        "lng",
        "speed",
        "heading",
        "course",
        "alt",
        "hdop",
        "track",
        "id",
        "note",
        "",
        "lat",
        "anomalyish",
        "ü",
    ]
)


@st.composite
def _csv_document(draw: st.DrawFn) -> bytes:
    delimiter = draw(st.sampled_from([",", ";", "\t", "|"]))
    newline = draw(st.sampled_from(["\n", "\r\n", "\r"]))
    header = draw(st.lists(_COLUMN, min_size=1, max_size=7))
    if draw(st.booleans()):
        header = ["t", "lat", "lon", *header]
    lines = [delimiter.join(header)]
    for _ in range(draw(st.integers(0, 25))):
        width = draw(st.sampled_from([len(header)] * 8 + [len(header) - 1, len(header) + 1]))
        lines.append(delimiter.join(draw(st.lists(_CELL, min_size=width, max_size=width))))
    return (newline.join(lines) + draw(st.sampled_from(["", newline]))).encode()


_COORD = st.one_of(_NUMBERS, st.floats(-200, 200).map(lambda v: f"{v:.6f}"))
_TIME = st.sampled_from(
    [
        "2024-05-01T10:00:00Z",
        "2024-05-01T10:00:01Z",
        "2024-05-01T09:59:59Z",
        "2024-05-01T10:00:00.5+02:00",
        "",
        "yesterday",
        "2024-02-30T00:00:00Z",
        "99999-01-01T00:00:00Z",
        "1970-01-01T00:00:00",
    ]
)


@st.composite
def _gpx_document(draw: st.DrawFn) -> bytes:
    points = []
    for _ in range(draw(st.integers(0, 12))):
        extra = draw(
            st.sampled_from(
                [
                    "",
                    "<ele>{}</ele>",
                    "<speed>{}</speed>",
                    "<extensions><gpxtpx:course>{}</gpxtpx:course></extensions>",
                    "<hdop>{}</hdop>",
                ]
            )
        ).format(draw(_NUMBERS))
        time = draw(_TIME)
        points.append(
            f'<trkpt lat="{draw(_COORD)}" lon="{draw(_COORD)}">'
            f"{f'<time>{time}</time>' if time else ''}{extra}</trkpt>"
        )
    segments = []
    while points:
        k = draw(st.integers(1, len(points)))
        segments.append("<trkseg>" + "".join(points[:k]) + "</trkseg>")
        points = points[k:]
    name = draw(
        st.sampled_from(["", "<name>drive</name>", "<name></name>", "<name>a&amp;b</name>"])
    )
    doctype = draw(st.sampled_from(["", '<!DOCTYPE gpx [<!ENTITY e "x">]>']))
    body = f"<trk>{name}{''.join(segments)}</trk>" * draw(st.integers(0, 2))
    waypoints = draw(st.sampled_from(["", '<wpt lat="1" lon="2"/>']))
    return (
        f'<?xml version="1.0"?>{doctype}<gpx version="1.1" '
        f'xmlns="http://www.topografix.com/GPX/1/1" '
        f'xmlns:gpxtpx="http://www.garmin.com/xmlschemas/TrackPointExtension/v1">'
        f"{waypoints}{body}</gpx>"
    ).encode()


_NMEA_FIELD = st.one_of(
    _NUMBERS,
    st.sampled_from(
        [
            "A",
            "V",
            "N",
            "S",
            "E",
            "W",
            "M",
            "1",
            "0",
            "4807.038",
            "01131.000",
            "123519",
            "230394",
            "999999",
            "5960.000",
        ]
    ),
)


@st.composite
def _nmea_document(draw: st.DrawFn) -> bytes:
    lines = []
    for _ in range(draw(st.integers(0, 20))):
        kind = draw(st.sampled_from(["GPGGA", "GNRMC", "GPRMC", "GPGSV", "PGRME", "GPGGA"]))
        if draw(st.integers(0, 3)) == 0:  # a plausible sentence with random damage
            fields = (
                [
                    "123519",
                    "4807.038",
                    "N",
                    "01131.000",
                    "E",
                    "1",
                    "08",
                    "0.9",
                    "545.4",
                    "M",
                    "46.9",
                    "M",
                    "",
                    "",
                ]
                if kind.endswith("GGA")
                else [
                    "123519",
                    "A",
                    "4807.038",
                    "N",
                    "01131.000",
                    "E",
                    "022.4",
                    "084.4",
                    "230394",
                    "003.1",
                    "W",
                ]
            )
            i = draw(st.integers(0, len(fields) - 1))
            fields[i] = draw(_NMEA_FIELD)
        else:
            fields = draw(st.lists(_NMEA_FIELD, max_size=14))
        body = ",".join([kind, *fields])
        checksum = nmea_checksum(body) ^ draw(st.sampled_from([0, 0, 0, 1]))
        ending = draw(st.sampled_from([f"*{checksum:02X}", f"*{checksum:02x}", "", "*G1"]))
        prefix = draw(st.sampled_from(["", "", "12:00:00 ", "$"]))
        lines.append(f"{prefix}${body}{ending}")
    return "\r\n".join(lines).encode()


# --- the one property ---------------------------------------------------------------


def _gradgps_error(action: Callable[[], T]) -> T | GradGPSError:
    """``action()``'s value, or the gradgps error it raised; anything else propagates."""
    try:
        return action()
    except GradGPSError as exc:
        return exc


def _survives(path: Path) -> None:
    """Read, convert and detect ``path``; only gradgps errors may come out."""
    fixes = _gradgps_error(lambda: to_fixes(read_table(path)))
    if isinstance(fixes, GradGPSError):
        assert str(fixes)
        return
    n = len(fixes)
    assert len(Detector().detect(fixes)) == n
    assert len(MultiTrackDetector().update_fixes(fixes)) == n


def _survives_chunked(path: Path, output: Path) -> None:
    summary = _gradgps_error(lambda: detect_csv_in_chunks(path, output, chunk_size=3))
    if isinstance(summary, GradGPSError):
        assert str(summary)
        assert not output.exists()
        return
    assert summary.rows == iter_csv_tables(path, 1).n_rows  # the structure pass's own count


@fuzz
@given(data=_mutated(_csv_document()))
def test_fuzz_csv_bytes(tmp_path: Path, data: bytes) -> None:
    output = tmp_path / "out.csv"
    output.unlink(missing_ok=True)
    path = tmp_path / "in.csv"
    path.write_bytes(data)
    _survives(path)
    _survives_chunked(path, output)


@fuzz
@given(data=_mutated(_gpx_document()))
def test_fuzz_gpx_bytes(tmp_path: Path, data: bytes) -> None:
    path = tmp_path / "in.gpx"
    path.write_bytes(data)
    _survives(path)


@fuzz
@given(data=_mutated(_nmea_document()))
def test_fuzz_nmea_bytes(tmp_path: Path, data: bytes) -> None:
    path = tmp_path / "in.nmea"
    path.write_bytes(data)
    _survives(path)


@fuzz
@given(data=st.binary(max_size=300), suffix=st.sampled_from([".csv.gz", ".gpx.gz", ".dat"]))
def test_fuzz_raw_bytes_any_format(tmp_path: Path, data: bytes, suffix: str) -> None:
    path = tmp_path / f"in{suffix}"
    path.write_bytes(data)
    _survives(path)


@fuzz
@given(fixes=messy_tracks(max_rows=80))
def test_fuzz_tracks(fixes: object) -> None:
    import pandas as pd

    assert isinstance(fixes, pd.DataFrame)
    batch = Detector().detect(fixes)
    streamed = MultiTrackDetector().update_fixes(fixes)
    bad = expected_reasons(fixes)
    assert len(batch) == len(streamed) == len(fixes)
    assert ((batch["invalid_reason"] != "").to_numpy()[bad]).all()
    # One semantics: batch reads each track in row order exactly as a stream does.
    assert batch["invalid_reason"].tolist() == streamed["invalid_reason"].tolist()
    assert batch["anomaly"].tolist() == streamed["anomaly"].tolist()


# --- tampered model directories -------------------------------------------------

_SCALAR = st.none() | st.booleans() | st.integers(-5, 10**6) | st.floats() | st.text(max_size=8)
# Scalars, or one level of list/object: deep enough to put a wrong type anywhere.
# (Not st.recursive: with st.data() it made hypothesis report flaky generation.)
_JSON = (
    _SCALAR
    | st.lists(_SCALAR, max_size=3)
    | st.dictionaries(st.text(max_size=5), _SCALAR, max_size=3)
)


def _paths(node: object, prefix: tuple[object, ...] = ()) -> list[tuple[object, ...]]:
    """Every key path into a JSON tree (dict keys and list indices)."""
    found = [prefix] if prefix else []
    if isinstance(node, dict):
        for key, value in node.items():
            found += _paths(value, (*prefix, key))
    elif isinstance(node, list):
        for i, value in enumerate(node):
            found += _paths(value, (*prefix, i))
    return found


@pytest.fixture(scope="module")
def shipped_model() -> tuple[dict[str, object], bytes]:
    import json

    from gradgps._grad.detector import _default_model_dir

    folder = _default_model_dir()
    return json.loads((folder / "config.json").read_text()), (folder / "weights.npz").read_bytes()


@fuzz
@given(data=st.data())
def test_fuzz_tampered_model_directory(
    tmp_path: Path, shipped_model: tuple[dict[str, object], bytes], data: st.DataObject
) -> None:
    import copy
    import json
    import tempfile

    config, weights = copy.deepcopy(shipped_model[0]), shipped_model[1]
    how = data.draw(st.sampled_from(["config", "config", "truncate weights", "truncate config"]))
    text = json.dumps(config)
    if how == "config":
        path = data.draw(st.sampled_from(_paths(config)))
        parent: object = config
        for key in path[:-1]:
            parent = parent[key]  # type: ignore[index]
        if data.draw(st.booleans()) and isinstance(parent, dict):
            del parent[path[-1]]
        else:
            parent[path[-1]] = data.draw(_JSON)  # type: ignore[index]
        text = json.dumps(config)
    elif how == "truncate config":
        text = text[: data.draw(st.integers(0, len(text) - 1))]
    else:
        weights = weights[: data.draw(st.integers(0, len(weights) - 1))]
    # A fresh folder per case: loaded models are cached by path and file times.
    folder = Path(tempfile.mkdtemp(dir=tmp_path))
    (folder / "config.json").write_text(text)
    (folder / "weights.npz").write_bytes(weights)
    det = _gradgps_error(lambda: Detector(folder))
    if isinstance(det, GradGPSError):
        assert str(folder) in str(det)  # names the file
        return
    assert how == "config"  # truncation is always caught (JSON syntax or the weights checksum)
    for i in range(3):
        result = det.update(float(i), 41.0 + 1e-4 * i, -96.0, 10.0, 90.0)
        assert result.invalid_reason == ""

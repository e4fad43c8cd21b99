"""Fuzzing: hostile tracks and file bytes may only ever raise gradgps's own errors.

Every case goes through the whole path a user's file takes: read (CSV,
GPX, NMEA, GeoJSON), convert to fixes, batch detection, streaming detection and, for
CSV, chunked detection to a file. The only exceptions allowed are
:class:`gradgps.GradGPSError` subclasses, whose messages name the problem;
anything else (a ``KeyError`` from deep inside pandas, a warning, which
pytest turns into an error) is a bug. When no error is raised, every input
row must come back as exactly one result row.

``make test`` runs a few dozen cases per test; ``make fuzz`` sets
``GRADGPS_FUZZ_EXAMPLES`` (2,500 per test, 35,000 in all) and builds the compiled
kernels with bounds checks (an out-of-bounds index is then an IndexError, not a
silent read or a SIGSEGV). Beyond files: ROS 1 and ROS 2 bags, Redis messages and
state keys (end to end and at the function level), and checkpoint states.
"""

from __future__ import annotations

import contextlib
import json
import os
import signal
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import TypeVar

import numpy as np
import pandas as pd
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from _track_strategies import expected_reasons, messy_tracks
from gradgps import GradGPSError, iter_csv_tables, read_table, to_fixes
from gradgps._grad.detector import Detector, MultiTrackDetector
from gradgps._io import geojson_rows
from gradgps._io.nmea import nmea_checksum
from gradgps._io.read import resolve_format, table_chunks
from gradgps._run.chunked import detect_csv_in_chunks

# Odd inputs on purpose: the Detector says so (gradgps.InputWarning); what is tested here
# is the answer it gives all the same.
pytestmark = pytest.mark.filterwarnings("ignore::gradgps.InputWarning")

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


_JSON_SCALAR = st.one_of(
    st.none(),
    st.booleans(),
    st.integers(-(2**63), 2**63 - 1),
    st.floats(allow_nan=False, allow_infinity=False),
    _JUNK,
    _TIME,
)
# Raw JSON text: what json.dumps never writes but files hold (the parser must refuse it).
_RAW = st.sampled_from(["NaN", "Infinity", "1e400", "18446744073709551616", "01", "'x'", ""])
# True about once in 60 draws (hypothesis favours the ends of an integer range).
_RARELY = st.sampled_from([False] * 59 + [True])


@st.composite
def _json_text(draw: st.DrawFn, value: object) -> str:
    """``value`` as JSON text; an object is a list of (key, value) pairs (a key may come
    twice), and now and then a scalar is raw text."""
    if isinstance(value, tuple):  # an object: its pairs
        members = [f"{json.dumps(k)}: {draw(_json_text(v))}" for k, v in value]
        return "{" + ", ".join(members) + "}"
    if isinstance(value, list):
        return "[" + ", ".join(draw(_json_text(v)) for v in value) + "]"
    if draw(_RARELY):
        return draw(_RAW)
    return json.dumps(value)


_NESTED_VALUE = st.recursive(
    _JSON_SCALAR,
    lambda inner: st.one_of(
        st.lists(inner, max_size=3),
        st.lists(st.tuples(_COLUMN, inner), max_size=3).map(tuple),
    ),
    max_leaves=6,
)
_POSITION = st.one_of(
    *[st.lists(st.floats(-200, 200), min_size=2, max_size=3)] * 6,
    st.lists(st.one_of(st.floats(-200, 200), _JSON_SCALAR), min_size=2, max_size=4),
    st.lists(_NESTED_VALUE, max_size=3),
)
_TIMES = st.lists(st.one_of(_TIME, _JSON_SCALAR, st.lists(_TIME, max_size=3)), max_size=8)
_GEOMETRY_TYPE = st.sampled_from(["Point", "LineString", "MultiLineString", "Polygon", "Point"])


@st.composite
def _geojson_feature(draw: st.DrawFn) -> object:
    kind = draw(_GEOMETRY_TYPE)
    vertices = st.lists(_POSITION, max_size=6)
    coordinates = {
        "Point": _POSITION,
        "LineString": vertices,
        "MultiLineString": st.lists(vertices, max_size=3),
        "Polygon": st.lists(vertices, max_size=2),
    }[kind]
    geometry = [
        ("type", kind),
        ("coordinates", draw(st.one_of(*[coordinates] * 8, _NESTED_VALUE))),
    ]
    props = draw(
        st.lists(
            st.tuples(
                st.one_of(_COLUMN, st.sampled_from(["name", "coordTimes", "times", "time"])),
                st.one_of(_NESTED_VALUE, _TIMES),
            ),
            max_size=5,
        )
    )
    members = [
        ("type", "Feature"),
        ("geometry", draw(st.sampled_from([tuple(geometry), tuple(reversed(geometry)), None]))),
        ("properties", draw(st.sampled_from([tuple(props)] * 8 + [None, []]))),
    ]
    if draw(_RARELY):  # a key given twice
        members.append(draw(st.sampled_from(members)))
    order = draw(st.permutations(members))
    if draw(_RARELY):  # not a feature
        return draw(st.sampled_from([None, 3, []]))
    return tuple(order)


@st.composite
def _geojson_document(draw: st.DrawFn) -> bytes:
    features = draw(st.lists(_geojson_feature(), max_size=6))
    if draw(st.integers(0, 4)) == 0 and features and isinstance(features[0], tuple):
        doc: object = features[0]  # a single Feature
    else:
        kind = draw(st.sampled_from(["FeatureCollection"] * 5 + ["Topology"]))
        members = [("type", kind), ("features", features)]
        doc = tuple(draw(st.permutations(members)))
    bom = draw(st.sampled_from(["", "", "\ufeff"]))
    return (bom + draw(_json_text(doc))).encode()


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


def _same_in_chunks(path: Path, feature_events: int | None = None) -> None:
    """GPX, NMEA and GeoJSON read in chunks of 3 rows (issue 18): a gradgps error exactly
    where the whole-file reader gives one (perhaps another of the file's errors: the
    chunks check values chunk by chunk), else the whole-file table, row for row.
    ``feature_events``: for GeoJSON, the events of a feature the chunks build in memory
    (fewer: more of its containers streamed by cursors of their own)."""
    if resolve_format(path) not in ("gpx", "nmea", "geojson"):  # mutated into CSV
        return
    whole = _gradgps_error(lambda: read_table(path))
    with pytest.MonkeyPatch.context() as patch:
        if feature_events is not None:
            patch.setattr(geojson_rows, "FEATURE_EVENTS", feature_events)
        chunks = _gradgps_error(lambda: list(table_chunks(path, 3)))
    if isinstance(whole, GradGPSError):
        assert isinstance(chunks, GradGPSError), "read whole: error; read in chunks: none"
        return
    assert not isinstance(chunks, GradGPSError), str(chunks)
    frame = pd.concat([t.frame for t in chunks], ignore_index=True)
    pd.testing.assert_frame_equal(frame, whole.frame)
    if whole.times is not None:
        np.testing.assert_array_equal(
            np.concatenate([np.asarray(t.times) for t in chunks]), whole.times
        )


@fuzz
@given(data=_mutated(_gpx_document()))
def test_fuzz_gpx_bytes(tmp_path: Path, data: bytes) -> None:
    path = tmp_path / "in.gpx"
    path.write_bytes(data)
    _survives(path)
    _same_in_chunks(path)


@fuzz
@given(data=_mutated(_nmea_document()))
def test_fuzz_nmea_bytes(tmp_path: Path, data: bytes) -> None:
    path = tmp_path / "in.nmea"
    path.write_bytes(data)
    _survives(path)
    _same_in_chunks(path)


@fuzz
@given(data=_mutated(_geojson_document()), feature_events=st.sampled_from([None, 0, 1, 5]))
def test_fuzz_geojson_bytes(tmp_path: Path, data: bytes, feature_events: int | None) -> None:
    path = tmp_path / "in.geojson"
    path.write_bytes(data)
    _survives(path)
    _same_in_chunks(path, feature_events)


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


# --- checkpoint states ----------------------------------------------------------


@pytest.fixture(scope="module")
def saved_states() -> list[dict[str, object]]:
    """States of one stream at several points: fresh, warming up (provisional period),
    steady, and just after a gap."""
    import json

    det = Detector()
    states = [json.loads(json.dumps(det.get_state()))]
    times = [0.0, 0.0011, 0.1, 1.0, 2.0, 3.0, 4.0, 5.0, 6.0, 20.0, 21.0, 22.0]
    for i, t in enumerate([*times, *[23.0 + k for k in range(30)]]):
        det.update(1.7e9 + t, 48.1 + 1e-5 * (i % 3), 11.5 + 1e-4 * i, 10.0 if i % 2 else None)
        if i in (0, 2, 5, 9, 11, 40):
            states.append(json.loads(json.dumps(det.get_state())))
    return states


def _nested(depth: int) -> object:
    node: object = 1.0
    for _ in range(depth):
        node = [node]
    return node


_JSONABLE_NUMBER = st.one_of(
    st.floats(allow_nan=False),
    st.integers(-(10**30), 10**30),
    st.sampled_from(["nan", "inf", "-inf", "x", 0.5, -1, 2**53, 1e300, True, None]),
    st.integers(2, 300).map(_nested),
    st.dictionaries(st.sampled_from(["S", "H", "format", ""]), _SCALAR, max_size=2),
)
# Beyond what json.dumps writes: a 300- to 5,000-digit integer (no float holds it) and
# junk nested up to 3,000 deep (past the interpreter's recursion limit).
_STATE_NUMBER = st.one_of(
    _JSONABLE_NUMBER,
    st.integers(300, 5000).map(lambda digits: 10**digits),
    st.integers(2, 3000).map(_nested),
)


def _tamper(
    state: dict[str, object], data: st.DataObject, number: st.SearchStrategy[object] = _STATE_NUMBER
) -> dict[str, object]:
    """``state`` (changed in place) with one to three of: a key deleted, added or replaced by
    any value; a list cut, extended, or one element (or an element's element) replaced."""
    for _ in range(data.draw(st.integers(1, 3))):
        if not state or data.draw(st.integers(0, 9)) == 0:
            state[data.draw(st.sampled_from(["extra", "S ", "warm", "tracks", ""]))] = data.draw(
                _JSON | number
            )
            continue
        key = data.draw(st.sampled_from(sorted(state)))
        value = state[key]
        how = data.draw(
            st.sampled_from(["element", "element", "truncate", "extend", "replace", "delete"])
        )
        if how == "delete":
            del state[key]
        elif how == "replace" or not isinstance(value, list) or not value:
            state[key] = data.draw(_JSON | number)
        elif how == "truncate":
            state[key] = value[: data.draw(st.integers(0, len(value) - 1))]
        elif how == "extend":
            state[key] = value + data.draw(st.lists(number, min_size=1, max_size=3))
        else:
            at = data.draw(st.integers(0, len(value) - 1))
            if isinstance(value[at], list) and value[at]:
                inner = list(value[at])
                inner[data.draw(st.integers(0, len(inner) - 1))] = data.draw(number)
                value[at] = inner
            else:
                value[at] = data.draw(number)
    return state


def _keeps_working(det: Detector, n: int = 24) -> None:
    """A restored detector takes ``n`` more fixes; each verdict is flagged or a score in [0, 1]
    with a finite repaired position."""
    import math

    t0 = det._last_t if det._last_t is not None else 1.7e9
    for i in range(1, n + 1):
        r = det.update(t0 + i, 48.1, 11.5 + 1e-4 * i)
        assert r.invalid_reason == "" or r.anomaly == 1
        if r.invalid_reason == "":
            assert 0.0 <= r.score <= 1.0
            assert math.isfinite(r.lat_clean)
            assert math.isfinite(r.lon_clean)


@fuzz
@given(data=st.data())
def test_fuzz_checkpoint_states(saved_states: list[dict[str, object]], data: st.DataObject) -> None:
    """A tampered state is refused with ConfigError, or restores a detector that works:
    never a crash, a hang or an out-of-bounds access in the compiled step (issue 18).
    (``make fuzz`` compiles the kernels with bounds checks: an out-of-bounds index there
    is an IndexError, which fails this test, instead of a silent read or a SIGSEGV.)"""
    import copy

    from gradgps import ConfigError

    state = _tamper(copy.deepcopy(data.draw(st.sampled_from(saved_states))), data)
    det = Detector()
    before = det.get_state()
    refused = _gradgps_error(lambda: det.set_state(state))
    if isinstance(refused, GradGPSError):
        assert isinstance(refused, ConfigError)
        assert str(refused)
        assert "\n" not in str(refused)
        assert det.get_state() == before  # a refused state leaves the detector as it was
        return
    _keeps_working(det)


@fuzz
@given(data=st.data())
def test_fuzz_multi_track_checkpoint_states(
    saved_states: list[dict[str, object]], data: st.DataObject
) -> None:
    """The same for a MultiTrackDetector's state (chunked detection's tracks): a tampered
    track state, a track id of another type or a damaged ``tracks`` mapping is refused with
    ConfigError, or every track keeps working."""
    import copy

    import pandas as pd

    from gradgps import ConfigError

    tracks: dict[object, object] = {
        name: copy.deepcopy(data.draw(st.sampled_from(saved_states))) for name in ("a", "b")
    }
    victim = data.draw(st.sampled_from(["a", "b"]))
    how = data.draw(st.sampled_from(["state", "state", "state", "id", "tracks", "top"]))
    state: object = {"tracks": tracks}
    if how == "state":
        _tamper(tracks[victim], data)  # type: ignore[arg-type]
    elif how == "id":
        tracks[data.draw(_SCALAR)] = tracks.pop(victim)
    elif how == "tracks":
        state = {"tracks": data.draw(_JSON | _STATE_NUMBER)}
    else:
        state = data.draw(_JSON | _STATE_NUMBER)
    multi = MultiTrackDetector()
    refused = _gradgps_error(lambda: multi.set_state(state))  # type: ignore[arg-type]
    if isinstance(refused, GradGPSError):
        assert isinstance(refused, ConfigError)
        assert str(refused)
        assert "\n" not in str(refused)
        return
    for det in multi.detectors.values():
        _keeps_working(det, 6)
    names = list(multi.detectors) or ["new"]
    fixes = pd.DataFrame(
        {
            "track": [names[i % len(names)] for i in range(12)],
            "t": [2e9 + i for i in range(12)],
            "lat": 48.1,
            "lon": [11.5 + 1e-4 * i for i in range(12)],
        }
    )
    assert len(multi.update_fixes(fixes)) == 12


# --- Redis messages ---------------------------------------------------------------

_FIELD_NAMES = st.sampled_from(
    [b"vehicle_id", b"t", b"lat", b"lon", b"speed", b"heading", b"self", b"t\xff", b"", b"extra"]
)
_FIELD_VALUES = st.one_of(
    st.sampled_from([b"a", b"b", b"\xff", b"\xc3(", b"", b"nan", b"inf", b"-0", b"1e400"]),
    st.floats(-200, 200).map(lambda x: repr(x).encode()),
    st.integers(0, 60).map(lambda x: str(1000 + x).encode()),
    st.binary(max_size=6),
)


@st.composite
def _redis_message(draw: st.DrawFn) -> list[bytes]:
    """A message's fields, flat: usually a well-formed fix, sometimes with any field
    repeated, dropped, or given a hostile name or value."""
    vehicle = draw(st.sampled_from([b"a", b"b", b"c"]))
    i = draw(st.integers(0, 60))
    fields = [
        b"vehicle_id",
        vehicle,
        b"t",
        str(1000 + i).encode(),
        b"lat",
        repr(48.1 + 1e-5 * i).encode(),
        b"lon",
        repr(11.5 + 1e-4 * i).encode(),
    ]
    for _ in range(draw(st.integers(0, 3))):
        how = draw(st.sampled_from(["add", "replace", "drop"]))
        if how == "add":
            fields += [draw(_FIELD_NAMES), draw(_FIELD_VALUES)]
        elif how == "replace":
            at = 2 * draw(st.integers(0, len(fields) // 2 - 1))
            fields[at + draw(st.integers(0, 1))] = draw(_FIELD_NAMES | _FIELD_VALUES)
        elif len(fields) > 2:
            at = 2 * draw(st.integers(0, len(fields) // 2 - 1))
            del fields[at : at + 2]
    return fields


@fuzz
@given(messages=st.lists(_redis_message(), min_size=1, max_size=12), workers=st.integers(1, 2))
def test_fuzz_redis_messages(messages: list[list[bytes]], workers: int) -> None:
    """Whatever producers write, every input message gets exactly one result, no worker
    stops and nothing stays pending (issue 18, items 2 and 3)."""
    fakeredis = pytest.importorskip("fakeredis")
    pytest.importorskip("lupa")
    from gradgps._run.fleet_redis import RedisStreamWorker

    server = fakeredis.FakeServer()
    raw = fakeredis.FakeRedis(server=server)
    ids = [raw.execute_command("XADD", "in", "*", *fields).decode() for fields in messages]
    pool = []
    for k in range(workers):
        client = fakeredis.FakeRedis(server=server, decode_responses=True)
        worker = RedisStreamWorker(client, "in", "out", "g", f"w{k}", batch_size=5)
        worker.ensure_group()
        pool.append(worker)
    for _ in range(50):
        reports = [w.step() for w in pool]
        if not any(r.routed_here or r.processed or r.taken_over for r in reports):
            break
    client = fakeredis.FakeRedis(server=server, decode_responses=True)
    out = [fields for _, fields in client.xrange("out")]
    assert sorted(f["source_id"] for f in out) == sorted(ids)
    assert client.xpending("in", "g")["pending"] == 0


# --- ROS bags -----------------------------------------------------------------------


@pytest.fixture(scope="module")
def ros1_bag(tmp_path_factory: pytest.TempPathFactory) -> bytes:
    """A small ROS 1 bag (``tests/_rosbag_support.py``: 30 NavSatFix at 1 Hz, one without a
    fix, and a TwistStamped topic at 10 Hz)."""
    pytest.importorskip("rosbags")
    from rosbags.rosbag1 import Writer
    from rosbags.typesys import Stores, get_typestore

    from _rosbag_support import write_drive

    store = get_typestore(Stores.ROS1_NOETIC)
    path = tmp_path_factory.mktemp("bag") / "drive.bag"
    with Writer(path) as writer:
        write_drive(writer, store, store.serialize_ros1)
    return path.read_bytes()


class _Hang(BaseException):
    """A case ran past its time limit (a BaseException: readers catch Exception)."""


@contextlib.contextmanager
def _time_limit(seconds: float) -> Iterator[None]:
    """Raise :class:`_Hang` in the block when it runs longer than ``seconds`` (main thread)."""

    def expire(signum: int, frame: object) -> None:
        raise _Hang(f"still running after {seconds} s")

    previous = signal.signal(signal.SIGALRM, expire)
    signal.setitimer(signal.ITIMER_REAL, seconds)
    try:
        yield
    finally:
        signal.setitimer(signal.ITIMER_REAL, 0)
        signal.signal(signal.SIGALRM, previous)


# Lengths and counts a damaged bag might hold (ROS 1 uses 32-bit, MCAP 64-bit fields).
_HOSTILE_LENGTHS = [0, 1, 2, 4, 8, 0x7F, 0xFF, 0xFFFF, 0x7FFFFFFF, 0x80000000, 0xFFFFFFFF]


def _damaged_binary(original: bytes) -> st.SearchStrategy[bytes]:
    """``original`` with one to three damages: cut off, bytes spliced in, a byte flipped,
    or a 4- or 8-byte little-endian field overwritten with a hostile length."""

    @st.composite
    def build(draw: st.DrawFn) -> bytes:
        data = original
        for _ in range(draw(st.integers(1, 3))):
            how = draw(st.sampled_from(["truncate", "splice", "flip", "flip", "length", "length"]))
            at = draw(st.integers(0, max(0, len(data) - 1)))
            if how == "truncate":
                data = data[:at]
            elif how == "splice":
                data = data[:at] + draw(st.binary(min_size=1, max_size=8)) + data[at:]
            elif not data:
                continue
            elif how == "flip":
                data = data[:at] + bytes([data[at] ^ draw(st.integers(1, 255))]) + data[at + 1 :]
            else:
                width = draw(st.sampled_from([4, 8]))
                value = draw(st.sampled_from(_HOSTILE_LENGTHS) | st.integers(0, 2**32 - 1))
                field = value.to_bytes(width, "little")
                data = data[:at] + field + data[at + width :]
        return data

    return build()


def _survives_bag(path: Path) -> None:
    """Read ``path`` as a bag within 60 s: rows, or a one-line gradgps error naming the file."""
    with _time_limit(60):
        table = _gradgps_error(lambda: read_table(path))
        if isinstance(table, GradGPSError):
            assert str(path) in str(table)
            assert "\n" not in str(table)  # the CLI's one `error:` line
            return
        _survives(path)


@fuzz
@given(data=st.data())
def test_fuzz_ros_bag_bytes(tmp_path: Path, ros1_bag: bytes, data: st.DataObject) -> None:
    """A damaged ROS 1 bag (cut off, bytes spliced in or flipped, a length field given a
    hostile value) is read or refused with an InputError, never a traceback from the bag
    library or a hang (issue 18, item 7)."""
    bag = data.draw(_mutated(st.just(ros1_bag)) | _damaged_binary(ros1_bag))
    path = tmp_path / "in.bag"
    path.write_bytes(bag)
    _survives_bag(path)


@pytest.fixture(scope="module")
def ros2_bags(tmp_path_factory: pytest.TempPathFactory) -> dict[str, dict[str, bytes]]:
    """Small ROS 2 bags (MCAP and SQLite storage) as their files' bytes: ``metadata.yaml``
    and the storage file, the drive of ``tests/_rosbag_support.py``."""
    pytest.importorskip("rosbags")
    from rosbags.rosbag2 import StoragePlugin, Writer
    from rosbags.typesys import Stores, get_typestore

    from _rosbag_support import write_drive

    store = get_typestore(Stores.ROS2_HUMBLE)
    bags: dict[str, dict[str, bytes]] = {}
    for name, plugin in (("mcap", StoragePlugin.MCAP), ("db3", StoragePlugin.SQLITE3)):
        path = tmp_path_factory.mktemp("bag2") / "drive"
        with Writer(path, version=9, storage_plugin=plugin) as writer:
            write_drive(writer, store, store.serialize_cdr)
        bags[name] = {f.name: f.read_bytes() for f in path.iterdir()}
    return bags


def _damaged_yaml(text: str) -> st.SearchStrategy[bytes]:
    """``metadata.yaml`` with a value replaced by junk, a line dropped, or damaged bytes."""
    lines = text.splitlines()

    @st.composite
    def edit(draw: st.DrawFn) -> bytes:
        edited = list(lines)
        at = draw(st.integers(0, len(edited) - 1))
        if draw(st.booleans()):
            del edited[at]
        else:
            key = edited[at].split(":", 1)[0]
            junk = draw(
                st.sampled_from(
                    ["", "-1", "1e400", "[]", "{}", "null", "~", "!!binary AA==", "*x", "&x [*x]"]
                )
                | st.integers(-(2**70), 2**70).map(str)
                | st.text(max_size=8)
            )
            edited[at] = f"{key}: {junk}"
        return "\n".join(edited).encode()

    return edit() | _damaged_binary(text.encode())


@fuzz
@given(data=st.data(), kind=st.sampled_from(["mcap", "db3"]))
def test_fuzz_ros2_bag_bytes(
    tmp_path: Path, ros2_bags: dict[str, dict[str, bytes]], data: st.DataObject, kind: str
) -> None:
    """A damaged ROS 2 bag, bare storage file (.mcap, .db3) or bag directory with a
    damaged ``metadata.yaml`` and/or storage file, is read or refused with an InputError,
    never another exception or a hang."""
    import tempfile

    files = ros2_bags[kind]
    storage = next(name for name in files if name.endswith(f".{kind}"))
    as_directory = data.draw(st.booleans())
    folder = Path(tempfile.mkdtemp(dir=tmp_path))
    if not as_directory:
        path = folder / f"in.{kind}"
        path.write_bytes(data.draw(_damaged_binary(files[storage])))
    else:
        path = folder / "bag"
        path.mkdir()
        damage = data.draw(st.sampled_from(["metadata", "storage", "both"]))
        metadata, content = files["metadata.yaml"], files[storage]
        if damage != "storage":
            metadata = data.draw(_damaged_yaml(metadata.decode()))
        if damage != "metadata":
            content = data.draw(_damaged_binary(content))
        (path / "metadata.yaml").write_bytes(metadata)
        (path / storage).write_bytes(content)
    _survives_bag(path)


# --- Redis messages and state keys, at the function level ----------------------------
# The worker's own decoding and per-message processing, fed hostile pages directly (no
# routing, no transactions): thousands of cases a second, where the end-to-end test above
# does tens.

_HOSTILE_NAMES = st.sampled_from(
    [
        *(b"vehicle_id", b"t", b"lat", b"lon", b"speed", b"heading", b"self", b"__class__"),
        *(b"kwargs", b"t\xff", b"\xc3(", b"", b"lat ", b"LAT", b"extra", b"x" * 300),
    ]
) | st.binary(max_size=6)
_HOSTILE_VALUES = st.one_of(
    st.sampled_from(
        [
            *(b"", b"nan", b"NaN", b"-nan", b"inf", b"-Infinity", b"1e400", b"-1e400", b"0x10"),
            *(b"1_000", b" 48.1 ", b"\xd9\xa1\xd9\xa2", b"48,1", b"\xff", b"\xc3(", b"\x00"),
            *(b"9" * 400, b"1" + b"0" * 5000, b"-" + b"9" * 4300 + b".5", b"1e-400"),
            b"4.9e-324",
        ]
    ),
    st.floats(allow_nan=True, allow_infinity=True).map(lambda x: repr(x).encode()),
    st.integers(-(10**30), 10**30).map(lambda x: str(x).encode()),
    st.binary(max_size=8),
)


@st.composite
def _hostile_page(draw: st.DrawFn) -> list[tuple[str, list[bytes]]]:
    """A page of messages in id order: mostly good fixes of vehicles a and b, some with any
    field repeated, dropped or added (any name, any bytes), an odd field count, or empty."""
    page = []
    ms = 1000
    for i in range(draw(st.integers(1, 12))):
        ms += draw(st.integers(0, 2))
        vehicle = draw(st.sampled_from([b"a", b"b"]))
        fields = [b"vehicle_id", vehicle, b"t", str(1000 + i).encode()]
        fields += [b"lat", repr(48.1 + 1e-5 * i).encode(), b"lon", repr(11.5 + 1e-4 * i).encode()]
        for _ in range(draw(st.integers(0, 3))):
            how = draw(st.sampled_from(["add", "add", "replace", "drop", "odd", "empty"]))
            if how == "add":
                fields += [draw(_HOSTILE_NAMES), draw(_HOSTILE_VALUES)]
            elif how == "replace" and fields:
                at = draw(st.integers(0, len(fields) - 1))
                fields[at] = draw(_HOSTILE_NAMES if at % 2 == 0 else _HOSTILE_VALUES)
            elif how == "drop" and len(fields) > 1:
                at = 2 * draw(st.integers(0, len(fields) // 2 - 1))
                del fields[at : at + 2]
            elif how == "odd":
                fields.append(draw(_HOSTILE_NAMES))
            elif how == "empty":
                fields = []  # a message deleted from the stream before it was read
        page.append((f"{ms}-{i}", fields))
    return page


@pytest.fixture(scope="module")
def redis_worker() -> object:
    """A worker object for its decoding and processing methods (the client is never used)."""
    fakeredis = pytest.importorskip("fakeredis")
    from gradgps._run.fleet_redis import RedisStreamWorker

    client = fakeredis.FakeRedis(server=fakeredis.FakeServer(), decode_responses=True)
    return RedisStreamWorker(client, "in", "out", "g", "w1")


def _process_page(
    worker: object, page: list[tuple[str, list[bytes]]], stored: dict[bytes, bytes | None]
) -> tuple[list[dict[str, str]], set[bytes], dict[bytes, str]]:
    """What the worker's transaction would write for ``page`` (outputs, changed vehicles,
    each vehicle's last message id; the states are in ``worker._fleet``), decoding the
    page as :data:`READ_SCRIPT` hands it over (hex)."""
    from gradgps._run.fleet_redis import RedisStreamWorker, _decode_message

    assert isinstance(worker, RedisStreamWorker)
    worker._tracks.clear()
    worker._dead = []
    messages = [_decode_message(i, [f.hex() for f in fields]) for i, fields in page]
    vehicles = sorted({m.vehicle for m in messages})
    tracks = {v: worker._restore(v, stored.get(v)) for v in vehicles}
    outputs, revisions, changed = worker._run_detectors(messages, tracks)
    assert len({r["source_id"] for r in revisions}) == len(revisions) <= len(outputs)
    return outputs, changed, {v: track.last_id for v, track in tracks.items()}


def _check_outputs(outputs: list[dict[str, str]], expected_ids: list[str]) -> None:
    """One output per message, in order, every field text that Redis can store, and every
    verdict flagged or a score in [0, 1] with a finite repaired position."""
    import math

    from gradgps._run.fleet_redis import OUTPUT_FIELDS, parse_output

    assert [o["source_id"] for o in outputs] == expected_ids
    for o in outputs:
        assert tuple(o) == OUTPUT_FIELDS
        assert all(isinstance(v, str) for v in o.values())
        "".join(o.values()).encode("utf-8")  # no lone surrogates: redis-py can send it
        r = parse_output(o)
        if r["invalid_reason"]:
            assert r["anomaly"] == 1
        else:
            assert 0.0 <= r["score"] <= 1.0
            assert math.isfinite(r["lat_clean"])
            assert math.isfinite(r["lon_clean"])


@fuzz
@given(page=_hostile_page())
def test_fuzz_redis_message_fields(
    redis_worker: object, page: list[tuple[str, list[bytes]]]
) -> None:
    """Any fields, any bytes: every message gets exactly one result, flagged when it cannot
    be used, and nothing raises (a processing error would be caught by the worker's safety
    net and dead-lettered: here that counts as a failure, since it hides a bug)."""
    import json

    from gradgps._run.fleet_redis import RedisStreamWorker

    outputs, changed, tracks = _process_page(redis_worker, page, {})
    _check_outputs(outputs, [i for i, _ in page])
    assert isinstance(redis_worker, RedisStreamWorker)
    assert redis_worker._dead == []
    for i, fields in page:
        names = fields[0::2]
        out = next(o for o in outputs if o["source_id"] == i)
        if len(set(names)) != len(names) or len(fields) % 2:
            assert out["invalid_reason"].startswith("bad message")  # repeated or odd
    # the states the transaction would store are strict JSON, and restore as they were
    for vehicle in changed:
        state = redis_worker._fleet.get_state(vehicle)
        record = json.dumps({"last_id": tracks[vehicle], "detector": state}, allow_nan=False)
        redis_worker._tracks.clear()  # not cached: restored from the record
        assert redis_worker._restore(vehicle, record.encode()).last_id == tracks[vehicle]
        assert redis_worker._dead == []
        assert redis_worker._fleet.get_state(vehicle) == state


def _lon(i: int) -> bytes:
    return repr(11.5 + 1e-4 * i).encode()


@pytest.fixture(scope="module")
def stored_record(redis_worker: object) -> bytes:
    """A vehicle's state key as the worker stores it, 30 fixes into a drive."""
    import json

    page = [
        (
            f"{1000 + i}-0",
            [b"vehicle_id", b"a", b"t", b"%d" % (1000 + i), b"lat", b"48.1", b"lon", _lon(i)],
        )
        for i in range(30)
    ]
    from gradgps._run.fleet_redis import RedisStreamWorker

    _, _, tracks = _process_page(redis_worker, page, {})
    assert isinstance(redis_worker, RedisStreamWorker)
    state = redis_worker._fleet.get_state(b"a")
    return json.dumps({"last_id": tracks[b"a"], "detector": state}).encode()


@fuzz
@given(data=st.data())
def test_fuzz_redis_state_keys(
    redis_worker: object, stored_record: bytes, data: st.DataObject
) -> None:
    """A damaged ``state:`` key (bytes cut, flipped or not UTF-8; the JSON's detector state
    tampered as in test_fuzz_checkpoint_states; ``last_id`` junk) never stops the page: it is
    restored, or the vehicle restarts with a fresh detector and one dead-letter entry. Either
    way every message gets one result, and none already processed is processed again."""
    import json

    from gradgps._run.fleet_redis import (
        _MESSAGE_ID,
        RedisStreamWorker,
        _decode_message,
        _id_key,
        _Track,
    )

    assert isinstance(redis_worker, RedisStreamWorker)
    how = data.draw(st.sampled_from(["bytes", "text", "state", "state", "last_id", "record"]))
    record = json.loads(stored_record)
    if how == "bytes":
        stored = data.draw(_damaged_binary(stored_record))
    elif how == "text":  # what json.dumps never writes: too deep, too many digits
        junk = data.draw(
            st.sampled_from([b"[" * 100_000 + b"]" * 100_000, b"1" * 5000, b"-" + b"9" * 4400])
        )
        key = data.draw(st.sampled_from([b'"H": ', b'"segment_count": ', b'"last_id": ']))
        stored = stored_record.replace(key, key + junk + b", " + key[:-2] + b"_was: ", 1)
    else:
        if how == "state":
            _tamper(record["detector"], data, _JSONABLE_NUMBER)
        elif how == "last_id":
            record["last_id"] = data.draw(
                _JSON | st.sampled_from(["0-0", "1029-0", "1029-1", "99999-0", "1-", "-1", "a-b"])
            )
        else:
            record = (
                data.draw(_JSON)
                if data.draw(st.booleans())
                else _tamper(record, data, _JSONABLE_NUMBER)
            )
        stored = json.dumps(record).encode()
    # What the worker must take from it: the record's last id when the JSON has a detector
    # and a well-formed last id (whether or not the detector state is refused), else 0-0.
    try:
        parsed = json.loads(stored)
        parsed["detector"]
        want_last = str(parsed["last_id"])
        if not _MESSAGE_ID.fullmatch(want_last):
            want_last = "0-0"
    except (ValueError, KeyError, TypeError, RecursionError):
        want_last = "0-0"
    redis_worker._tracks.clear()
    redis_worker._dead = []
    last_id = redis_worker._restore(b"a", stored).last_id
    dead = list(redis_worker._dead)
    assert last_id == want_last
    assert len(dead) <= 1
    if dead:
        assert "fresh detector" in dead[0]["problem"]
        assert redis_worker._fleet.get_state(b"a") == Detector().get_state()
    page = [
        (
            f"{1025 + k}-0",
            [b"vehicle_id", b"a", b"t", b"%d" % (1025 + k), b"lat", b"48.1", b"lon", _lon(25 + k)],
        )
        for k in range(10)
    ]
    messages = [_decode_message(i, [f.hex() for f in fields]) for i, fields in page]
    outputs, _, _ = redis_worker._run_detectors(messages, {b"a": _Track(last_id)})
    assert redis_worker._dead == dead  # no message's processing failed
    # resent messages (not after the stored last id) get no second result; the rest one each
    _check_outputs(outputs, [i for i, _ in page if _id_key(i) > _id_key(want_last)])

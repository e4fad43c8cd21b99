"""GPX reading: tracks and segments, values and extensions, malformed files."""

from __future__ import annotations

import gzip
from pathlib import Path

import numpy as np
import pytest

from gradgps import InputError, to_fixes
from gradgps._io.gpx import read_gpx
from gradgps._io.read import read_fixes, read_table

GPX11 = """<?xml version="1.0" encoding="UTF-8"?>
<gpx version="1.1" creator="test" xmlns="http://www.topografix.com/GPX/1/1"
     xmlns:gpxtpx="http://www.garmin.com/xmlschemas/TrackPointExtension/v2">
  <wpt lat="1" lon="2"><name>home</name></wpt>
  <trk>
    <name>Morning drive</name>
    <trkseg>
      <trkpt lat="41.25" lon="-95.98"><ele>350.5</ele><time>2019-05-23T20:54:11Z</time>
        <hdop>1.2</hdop>
        <extensions><gpxtpx:TrackPointExtension>
          <gpxtpx:speed>13.5</gpxtpx:speed><gpxtpx:course>270.5</gpxtpx:course>
        </gpxtpx:TrackPointExtension></extensions>
      </trkpt>
      <trkpt lat="41.2501" lon="-95.9802"><ele>351</ele><time>2019-05-23T20:54:12.500Z</time></trkpt>
    </trkseg>
    <trkseg>
      <trkpt lat="41.26" lon="-95.99"><time>2019-05-23T22:54:20+02:00</time></trkpt>
    </trkseg>
  </trk>
  <trk>
    <trkseg>
      <trkpt lat="-33.5" lon="151.25"><time>2019-05-24T00:00:00Z</time></trkpt>
    </trkseg>
  </trk>
</gpx>
"""

GPX10 = """<?xml version="1.0"?>
<gpx version="1.0" creator="old" xmlns="http://www.topografix.com/GPX/1/0">
  <trk><name>a</name><trkseg>
    <trkpt lat="10.0" lon="20.0"><ele>5</ele><time>2004-01-01T00:00:00Z</time>
      <course>45.0</course><speed>2.5</speed></trkpt>
    <trkpt lat="10.001" lon="20.001"><time>2004-01-01T00:00:01Z</time>
      <course>46.0</course><speed>2.75</speed></trkpt>
  </trkseg></trk>
</gpx>
"""


def write(tmp_path: Path, text: str, name: str = "t.gpx") -> Path:
    path = tmp_path / name
    path.write_text(text, encoding="utf-8")
    return path


def test_gpx11_tracks_segments_and_values(tmp_path: Path) -> None:
    table = read_table(write(tmp_path, GPX11))
    frame = table.frame
    assert frame["track"].tolist() == [
        "Morning drive/0",
        "Morning drive/0",
        "Morning drive/1",
        "1/0",
    ]
    assert list(frame.columns) == ["track", "time", "lat", "lon", "alt", "speed", "course", "hdop"]
    np.testing.assert_array_equal(frame["alt"], [350.5, 351.0, np.nan, np.nan])
    np.testing.assert_array_equal(frame["speed"], [13.5, np.nan, np.nan, np.nan])
    np.testing.assert_array_equal(frame["course"], [270.5, np.nan, np.nan, np.nan])
    np.testing.assert_array_equal(frame["hdop"], [1.2, np.nan, np.nan, np.nan])
    fixes = to_fixes(table)
    start = 1558644851.0
    np.testing.assert_array_equal(fixes["t"], [start, start + 1.5, start + 9.0, start + 11149.0])
    assert fixes["lat"].tolist() == [41.25, 41.2501, 41.26, -33.5]
    assert fixes["heading"].iloc[0] == 270.5


def test_gpx10_direct_speed_and_course(tmp_path: Path) -> None:
    fixes = read_fixes(write(tmp_path, GPX10))
    assert fixes["speed"].tolist() == [2.5, 2.75]
    assert fixes["heading"].tolist() == [45.0, 46.0]
    assert fixes["track"].tolist() == ["a/0", "a/0"]


def test_repeated_track_names_stay_distinct(tmp_path: Path) -> None:
    point = '<trkpt lat="1" lon="2"><time>2020-01-01T00:00:00Z</time></trkpt>'
    text = f"<gpx><trk><name>r</name><trkseg>{point}</trkseg></trk><trk><name>r</name><trkseg>{point}</trkseg></trk></gpx>"
    assert read_gpx(write(tmp_path, text)).frame["track"].tolist() == ["r/0", "r #1/0"]


def test_points_without_time_are_kept_as_missing(tmp_path: Path) -> None:
    text = '<gpx><trk><trkseg><trkpt lat="1" lon="2"/><trkpt lat="1" lon="2"><time>2020-01-01T00:00:00Z</time></trkpt></trkseg></trk></gpx>'
    fixes = read_fixes(write(tmp_path, text))
    assert np.isnan(fixes["t"].iloc[0])
    assert fixes["t"].iloc[1] == 1577836800.0


def test_gzipped_gpx(tmp_path: Path) -> None:
    path = tmp_path / "t.gpx.gz"
    path.write_bytes(gzip.compress(GPX10.encode()))
    assert len(read_fixes(path)) == 2


@pytest.mark.parametrize(
    ("text", "match", "line"),
    [
        (GPX11[: GPX11.index("<trkseg>", 400)], "malformed XML: no element found", 16),
        (
            GPX11.replace(
                "</ele><time>2019-05-23T20:54:11Z", "</elevation><time>2019-05-23T20:54:11Z"
            ),
            "malformed XML: mismatched tag",
            8,
        ),
        ("", "malformed XML: no element found", 1),
        ("lat,lon\n1,2\n", "malformed XML: syntax error", 1),
        (
            GPX11.replace('lat="41.2501"', 'lat="41.25O1"'),
            "track point lat is not a number: '41.25O1'",
            14,
        ),
        (
            GPX11.replace("2019-05-23T20:54:12.500Z", "yesterday"),
            "track point time is not ISO-8601: 'yesterday'",
            14,
        ),
        (
            '<gpx version="1.1"><wpt lat="1" lon="2"/><rte><rtept lat="1" lon="2"/></rte></gpx>',
            r"no track points \(<trkpt>\) in the file \(2 waypoints/route points",
            None,
        ),
        ('<gpx version="1.1"></gpx>', "no track points", None),
    ],
    ids=[
        "truncated",
        "bad-xml",
        "empty",
        "not-xml",
        "bad-lat",
        "bad-time",
        "only-waypoints",
        "no-points",
    ],
)
def test_malformed_gpx(tmp_path: Path, text: str, match: str, line: int | None) -> None:
    path = write(tmp_path, text)
    with pytest.raises(InputError, match=match) as info:
        read_table(path)
    assert info.value.line == line
    assert str(path) in str(info.value)


def test_binary_garbage_gpx(tmp_path: Path) -> None:
    path = tmp_path / "noise.gpx"
    path.write_bytes(np.random.default_rng(1).integers(0, 256, 2048, dtype=np.uint8).tobytes())
    with pytest.raises(InputError, match="malformed XML"):
        read_table(path)

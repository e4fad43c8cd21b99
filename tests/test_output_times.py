"""Output times in the input's own form, the same text in every mode (issue 14, item 6).

One input, every mode: chunked CSV, whole file (the file read whole and
detected at once, ``tests/_whole_file.py``: ``--chunk-size 0`` reads in chunks), Parquet output, ``--follow``, and the report's anomaly table must write the
same ``time`` text for the same fix. NMEA and GPX (times assembled from
fields) are written as ISO-8601 UTC; CSV times stay as the input wrote them.
"""

from __future__ import annotations

import csv
import io
import re
from pathlib import Path

import pandas as pd
import pytest
from click.testing import CliRunner

from _whole_file import detect_whole
from gradgps import ColumnMap, read_fixes, read_table, to_fixes
from gradgps._cli import main
from gradgps._io.nmea import nmea_checksum
from gradgps._run.follow import follow_lines

JUMP = 40  # the row with a 550 m jump: flagged, so the report's anomaly table lists it


def _sentence(body: str) -> str:
    return f"${body}*{nmea_checksum(body):02X}"


def _hms(k: int) -> str:
    sec = 10 * 3600 + k
    return f"{sec // 3600:02d}{sec % 3600 // 60:02d}{sec % 60:02d}"


def _nmea(path: Path, *, dated: bool = True) -> Path:
    """60 epochs at 1 Hz heading north at 18.5 m/s; odd epochs at .20 s; one jump."""
    lines = []
    for k in range(60):
        tod = _hms(k) + (".20" if k % 2 else ".00")
        minutes = 7.038 + k * 0.01 + (0.3 if k == JUMP else 0.0)
        lat = f"48{minutes:07.4f},N"
        if dated:
            lines.append(_sentence(f"GPRMC,{tod},A,{lat},01131.000,E,036.0,000.0,231126,003.1,W"))
        lines.append(_sentence(f"GPGGA,{tod},{lat},01131.000,E,1,08,0.9,545.4,M,46.9,M,,"))
    path.write_text("\n".join(lines) + "\n", encoding="ascii")
    return path


def _run(args: list[str]) -> str:
    result = CliRunner().invoke(main, args)
    assert result.exit_code == 0, result.output
    return result.stdout


def _times_csv(path: Path, column: str) -> list[str]:
    with path.open(encoding="utf-8", newline="") as f:
        return [row[column] for row in csv.DictReader(f)]


def _follow_times(path: Path) -> list[str]:
    """``time`` of each scored line of ``detect --follow`` (one per epoch)."""
    rows = list(csv.DictReader(io.StringIO(_run(["detect", "--follow", str(path)]))))
    return [r["time"] for r in rows if r["epoch_line"] == r["line"]]


def _report_times(path: Path) -> list[str]:
    """The time cells of the report's anomaly table."""
    html = path.read_text(encoding="utf-8")
    table = html.split("<h2 id='anomalies'>", 1)[1].split("</table>", 1)[0]
    return [
        re.findall(r"<td>(.*?)</td>", row)[2] for row in re.findall(r"<tr>(<td>.*?)</tr>", table)
    ]


def test_nmea_times_are_iso_utc_in_batch_parquet_follow_and_report(tmp_path: Path) -> None:
    pytest.importorskip("matplotlib")
    pytest.importorskip("pyarrow")
    log = _nmea(tmp_path / "drive.nmea")
    _run(
        [
            "detect",
            str(log),
            "-o",
            str(tmp_path / "out.csv"),
            "--report",
            str(tmp_path / "report.html"),
        ]
    )
    _run(["detect", str(log), "-o", str(tmp_path / "out.parquet")])
    batch = _times_csv(tmp_path / "out.csv", "time")
    assert batch[:3] == ["2026-11-23T10:00:00Z", "2026-11-23T10:00:01.200Z", "2026-11-23T10:00:02Z"]
    assert len(batch) == 60
    assert pd.read_parquet(tmp_path / "out.parquet")["time"].tolist() == batch
    assert _follow_times(log) == batch
    assert _report_times(tmp_path / "report.html") == [batch[JUMP]]
    # The detector still sees the exact seconds, not the text.
    fixes = read_fixes(log)
    assert fixes["t"].iloc[1] == pytest.approx(1795428001.2)


def test_nmea_without_a_date_gives_the_time_of_day_in_batch_and_follow(tmp_path: Path) -> None:
    log = _nmea(tmp_path / "gga.nmea", dated=False)
    _run(["detect", str(log), "-o", str(tmp_path / "out.csv")])
    batch = _times_csv(tmp_path / "out.csv", "time")
    assert batch[:2] == ["10:00:00Z", "10:00:01.200Z"]
    assert _follow_times(log) == batch
    table = read_table(log)
    assert any("without a date" in note for note in table.notes or [])
    # The output reads back (inject, a second tool): times of day counted from midnight.
    again = read_fixes(tmp_path / "out.csv", columns=ColumnMap(lat="lat", lon="lon"))
    assert again["t"].iloc[:2].tolist() == [36000.0, 36001.2]


def test_times_of_day_read_back_across_midnight() -> None:
    frame = pd.DataFrame(
        {"time": ["23:59:59Z", "00:00:00.500Z", "00:00:01Z"], "lat": 48.1, "lon": 11.5}
    )
    assert to_fixes(frame)["t"].tolist() == [86399.0, 86400.5, 86401.0]


def test_follow_takes_the_date_once_an_rmc_gives_it_and_ignores_a_stale_one() -> None:
    lines = [_sentence("GPGGA,235958,4807.038,N,01131.000,E,1,08,0.9,545.4,M,46.9,M,,")]
    for tod, date in (("235959", "311219"), ("000000", "311219"), ("000001", "010120")):
        lines.append(_sentence(f"GPRMC,{tod},A,4807.038,N,01131.000,E,022.4,084.4,{date},003.1,W"))
    out: list[str] = []
    follow_lines(lines, out.append)
    times = [r["time"] for r in csv.DictReader(io.StringIO("\n".join(out)))]
    # Before the first RMC there is no date yet: the time of day alone.
    assert times == [
        "23:59:58Z",
        "2019-12-31T23:59:59Z",
        "2020-01-01T00:00:00Z",
        "2020-01-01T00:00:01Z",
    ]


def _gpx(path: Path) -> Path:
    points = "".join(
        f'<trkpt lat="{48.1173 + k * 1.6e-4 + (0.005 if k == JUMP else 0.0):.7f}" '
        f'lon="11.5166667"><time>2026-11-23T10:00:{k:02d}Z</time></trkpt>'
        for k in range(60)
    )
    path.write_text(
        '<?xml version="1.0"?><gpx version="1.1" xmlns="http://www.topografix.com/GPX/1/1">'
        f"<trk><trkseg>{points}</trkseg></trk></gpx>",
        encoding="utf-8",
    )
    return path


def test_gpx_times_come_out_as_the_file_wrote_them(tmp_path: Path) -> None:
    pytest.importorskip("pyarrow")
    gpx = _gpx(tmp_path / "drive.gpx")
    _run(["detect", str(gpx), "-o", str(tmp_path / "out.csv")])
    _run(["detect", str(gpx), "-o", str(tmp_path / "out.parquet")])
    expected = [f"2026-11-23T10:00:{k:02d}Z" for k in range(60)]
    assert _times_csv(tmp_path / "out.csv", "time") == expected
    assert pd.read_parquet(tmp_path / "out.parquet")["time"].tolist() == expected


def _csv(path: Path, times: list[str]) -> Path:
    rows = ["time,lat,lon"] + [
        f"{t},{48.1173 + k * 1.6e-4 + (0.005 if k == JUMP else 0.0):.7f},11.5166667"
        for k, t in enumerate(times)
    ]
    path.write_text("\n".join(rows) + "\n", encoding="utf-8")
    return path


@pytest.mark.parametrize(
    ("times", "report_text"),
    [
        # ISO text with its own offset: the same text everywhere, the report included.
        ([f"2026-11-23T11:00:{k:02d}+01:00" for k in range(60)], "2026-11-23T11:00:40+01:00"),
        # Epoch numbers: the same numbers in every output; the report makes them readable.
        ([f"{1795428000 + k}" for k in range(60)], "2026-11-23 10:00:40.0 UTC"),
    ],
)
def test_csv_times_are_the_same_text_in_every_mode(
    tmp_path: Path, times: list[str], report_text: str
) -> None:
    pytest.importorskip("matplotlib")
    pytest.importorskip("pyarrow")
    data = _csv(tmp_path / "drive.csv", times)
    chunked, whole = tmp_path / "chunked.csv", tmp_path / "whole.csv"
    report = tmp_path / "report.html"
    _run(["detect", str(data), "-o", str(chunked), "--chunk-size", "7", "--report", str(report)])
    detect_whole(data, whole)
    _run(["detect", str(data), "-o", str(tmp_path / "out.parquet")])
    assert _times_csv(chunked, "time") == times
    assert _times_csv(whole, "time") == times
    parquet = pd.read_parquet(tmp_path / "out.parquet")["time"]
    assert [str(v) for v in parquet] == times
    follow = list(csv.DictReader(io.StringIO(_run(["detect", "--follow", str(data)]))))
    assert [r["time"] for r in follow] == times
    assert _report_times(report) == [report_text]


def test_parquet_timestamps_are_written_to_csv_as_iso_8601(tmp_path: Path) -> None:
    pytest.importorskip("pyarrow")
    seconds = [1795428000.0 + k + (0.25 if k == 3 else 0.0) for k in range(60)]
    frame = pd.DataFrame(
        {
            "time": pd.to_datetime(seconds, unit="s", utc=True),
            "lat": [48.1173 + k * 1.6e-4 for k in range(60)],
            "lon": 11.5166667,
        }
    )
    frame.to_parquet(tmp_path / "drive.parquet")
    _run(["detect", str(tmp_path / "drive.parquet"), "-o", str(tmp_path / "out.csv")])
    _run(["detect", str(tmp_path / "drive.parquet"), "-o", str(tmp_path / "out.parquet")])
    text = _times_csv(tmp_path / "out.csv", "time")
    assert text[:4] == [
        "2026-11-23T10:00:00Z",
        "2026-11-23T10:00:01Z",
        "2026-11-23T10:00:02Z",
        "2026-11-23T10:00:03.250Z",
    ]
    assert text[4:] == [f"2026-11-23T10:00:{k:02d}Z" for k in range(4, 60)]
    # Parquet to Parquet keeps the column's own type.
    kept = pd.read_parquet(tmp_path / "out.parquet")["time"]
    assert pd.api.types.is_datetime64_any_dtype(kept.dtype)


@pytest.mark.parametrize("count_line", [False, True])
def test_event_times_are_iso_in_every_mode_for_an_iso_input(
    tmp_path: Path, count_line: bool
) -> None:
    """`--events` gives start/end in the input's form whatever the chunking: the chunked
    run used to re-read the file for a sample of its times, which failed without
    `--report` (nothing kept to look at) and on a leading row-count line (GPSLogger)."""
    from gradgps._data.inject import inject_grad
    from gradgps._data.simulator import simulate_fleet

    drive = inject_grad(simulate_fleet(1, 5.0, 1.0, 3, imu=False)[["t", "lat", "lon"]], seed=2)
    drive = drive[["t", "lat", "lon"]]
    drive["t"] = pd.to_datetime(drive["t"], unit="s", utc=True).dt.strftime("%Y-%m-%dT%H:%M:%SZ")
    source = tmp_path / "in.csv"
    text = drive.to_csv(index=False)
    source.write_text((f"{len(drive)}\n" if count_line else "") + text)
    starts = []
    for chunk in ("1000", "0"):
        events = tmp_path / f"events{chunk}.csv"
        run = CliRunner().invoke(
            main, ["detect", str(source), "--events", str(events), "--chunk-size", chunk]
        )
        assert run.exit_code == 0, run.output
        starts.append(pd.read_csv(events)["start"].astype(str).tolist())
    assert starts[0], "the injected faults make events"
    assert starts[0] == starts[1]
    assert all(re.fullmatch(r"\d{4}-\d\d-\d\dT[\d:.]+Z", s) for s in starts[0])

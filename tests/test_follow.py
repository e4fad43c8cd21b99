"""Live follow mode: one flushed result line per input line, never a crash on bad lines."""

from __future__ import annotations

import csv
import io
import os
import subprocess
import sys
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from click.testing import CliRunner

from _detector_checks import final_verdicts
from gradgps._cli import main
from gradgps._data.simulator import simulate_drive
from gradgps._exceptions import InputError
from gradgps._grad.detector import Detector
from gradgps._io.nmea import nmea_checksum
from gradgps._run.follow import RESULT_FIELDS, follow_lines, parse_time

REPO = Path(__file__).resolve().parents[1]


def _sentence(body: str) -> str:
    return f"${body}*{nmea_checksum(body):02X}"


@pytest.fixture(scope="module")
def drive_csv() -> str:
    drive = simulate_drive(minutes=1.0, seed=1)
    frame = drive[["t", "lat", "lon", "speed", "heading"]].head(40)
    return frame.to_csv(index=False)


def _rows(lines: list[str]) -> list[dict[str, str]]:
    return list(csv.DictReader(io.StringIO("\n".join(lines))))


def test_csv_stream_matches_detector_update_and_keeps_bad_lines(drive_csv):
    lines = drive_csv.splitlines()
    bad = ["1700000100,91.5,7,1,1", "1,2", "soon,41.2,-95.9,1,1", ""]
    out: list[str] = []
    counts = follow_lines([*lines, *bad], out.append)
    rows = _rows(out)
    n = len(lines) - 1  # the header is consumed
    assert len(rows) == n + 3  # the blank line is skipped
    assert list(rows[0]) == ["t", "lat", "lon", "speed", "heading", *RESULT_FIELDS]
    detector = Detector()
    for row in rows[:n]:
        expected = detector.update(
            float(row["t"]),
            float(row["lat"]),
            float(row["lon"]),
            float(row["speed"]),
            float(row["heading"]),
        )
        assert int(row["anomaly"]) == expected.anomaly
        assert float(row["score"]) == pytest.approx(expected.score, rel=1e-9)
        assert float(row["lat_clean"]) == pytest.approx(expected.lat_clean, abs=1e-9)
    reasons = [r["invalid_reason"] for r in rows[n:]]
    assert reasons[0] == "latitude outside +-90"
    assert reasons[1] == "expected 5 fields as in the header, got 2"
    assert "not a time" in reasons[2]
    assert all(r["anomaly"] == "1" for r in rows[n:])
    assert (counts.lines, counts.fixes, counts.invalid) == (n + 3, n, 3)


def test_one_detector_per_track():
    lines = ["track,time,lat,lon"]
    for i in range(6):
        lines += [f"a,{i},48.0,{11 + i * 1e-4}", f"b,{i},10.0,{20 + i * 1e-4}"]
    out: list[str] = []
    follow_lines(lines, out.append)
    rows = _rows(out)
    assert all(
        r["invalid_reason"] == "" for r in rows
    )  # interleaved times stay increasing per track
    a = Detector()
    for r in rows[::2]:
        assert float(r["score"]) == pytest.approx(
            a.update(float(r["time"]), float(r["lat"]), float(r["lon"])).score
        )


def test_nmea_stream_scores_each_epoch_once():
    lines = _nmea_lines()
    lines += [
        GSV,
        "$GPGGA,123519,4807.038,N,01131.000,E,1,08,0.9,545.4,M,46.9,M,,*00",
        "garbage",
    ]
    out: list[str] = []
    counts = follow_lines(lines, out.append)
    rows = _rows(out)
    assert len(rows) == len(lines)
    assert [r["line"] for r in rows] == [str(i + 1) for i in range(len(lines))]
    # The RMC of an instant repeats the verdict its GGA got, and says which line was scored.
    assert rows[1]["epoch_line"] == "1"
    assert rows[1]["score"] == rows[0]["score"]
    # Times as the batch reader writes NMEA times: the date comes with the first RMC.
    assert [rows[k]["time"] for k in (0, 1, 2)] == [
        "12:35:10Z",
        "1994-03-23T12:35:10Z",
        "1994-03-23T12:35:11Z",
    ]
    assert rows[10]["invalid_reason"] == "not a fix sentence"
    assert rows[10]["anomaly"] == ""
    assert rows[11]["invalid_reason"].startswith("rejected sentence: GGA checksum mismatch")
    assert rows[12]["invalid_reason"] == "not a fix sentence"
    assert (counts.fixes, counts.invalid) == (5, 3)


def test_nmea_stream_times_keep_growing_across_midnight_with_a_stale_date():
    # Follow mode counts from the first sentence's date, so a stale date after
    # midnight (issue 18) cannot send a fix back a day.
    lines = []
    for tod, date in (("235958", "311219"), ("235959", "311219"), ("000000", "311219")):
        lines.append(_sentence(f"GPRMC,{tod},A,4807.038,N,01131.000,E,022.4,084.4,{date},003.1,W"))
    lines.append(_sentence("GPGGA,000001,4807.038,N,01131.000,E,1,08,0.9,545.4,M,46.9,M,,"))
    out: list[str] = []
    follow_lines(lines, out.append)
    assert [r["time"] for r in _rows(out)] == [
        "2019-12-31T23:59:58Z",
        "2019-12-31T23:59:59Z",
        "2020-01-01T00:00:00Z",
        "2020-01-01T00:00:01Z",
    ]


@pytest.mark.parametrize(
    ("text", "seconds"),
    [
        ("1700000000", 1700000000.0),
        ("1700000000500", 1700000000.5),
        ("2023-11-14T22:13:20Z", 1700000000.0),
        ("2023-11-14 22:13:20", 1700000000.0),
    ],
)
def test_parse_time(text, seconds):
    assert parse_time(text) == pytest.approx(seconds)


def test_cli_follow_with_stdin(drive_csv):
    result = CliRunner().invoke(main, ["detect", "--follow", "-"], input=drive_csv)
    assert result.exit_code == 0, result.output
    out = [line for line in result.stdout.splitlines() if line]
    assert len(out) == len(drive_csv.splitlines())  # header + one line per fix
    assert f"followed {len(out) - 1} lines" in result.stderr
    # a live reader is told why a line's answer waits for the next fix
    assert ("note: this model settles each verdict" in result.stderr) == bool(_lag())


def _follow_stdin(stderr: int) -> subprocess.Popen[str]:
    """``gradgps detect --follow -`` in its own process, line-buffered text pipes: a real
    stream, for the tests that check what arrives before the next line is sent."""
    env = {**os.environ, "PYTHONPATH": str(REPO / "src"), "OMP_NUM_THREADS": "1"}
    return subprocess.Popen(
        [sys.executable, "-m", "gradgps", "detect", "--follow", "-"],
        stdin=subprocess.PIPE,
        stdout=subprocess.PIPE,
        stderr=stderr,
        text=True,
        env=env,
        bufsize=1,
    )


def _lag() -> int:
    """Fixes a line waits for its answer with the shipped model: 1 where its verdicts settle
    one fix late (a confirm head), else 0."""
    model = Detector().model_
    return 1 if model.params.settles(model.dims) else 0


def test_each_result_is_written_before_the_next_line_arrives(drive_csv):
    """A real pipe: the answer to line k arrives as soon as its verdict is final, before
    line k+1 is sent (k+2 where the shipped model settles each verdict with the next fix);
    the end of the input lets the last one out."""
    lag = _lag()
    with _follow_stdin(subprocess.DEVNULL) as proc:
        assert proc.stdin is not None
        assert proc.stdout is not None
        lines = drive_csv.splitlines()
        try:
            proc.stdin.write(lines[0] + "\n")
            proc.stdin.flush()
            assert proc.stdout.readline().startswith("t,lat,lon,speed,heading,anomaly")
            fixes = lines[1:5]
            for k, line in enumerate(fixes):
                proc.stdin.write(line + "\n")
                proc.stdin.flush()
                if k < lag:
                    continue
                answer = proc.stdout.readline().rstrip("\n").split(",")
                assert answer[:5] == fixes[k - lag].split(",")
                assert np.isfinite(float(answer[6]))
        finally:
            proc.stdin.close()
            rest = proc.stdout.read()
            proc.wait(timeout=60)
    assert proc.returncode == 0
    assert [r.split(",")[:5] for r in rest.splitlines()] == [
        f.split(",") for f in fixes[len(fixes) - lag :]
    ]


#: A satellites-in-view sentence: not a fix.
GSV = "$GPGSV,3,1,11,03,03,111,00,04,15,270,00,06,01,010,00,13,06,292,00*74"


def _nmea_lines(
    epochs: int = 5, first_second: int = 10, lat_milli: Callable[[int], int] = lambda k: 38 + k
) -> list[str]:
    """A GGA and an RMC sentence per instant, one instant a second from 12:35:``first_second``,
    at latitude 48°07.``lat_milli(k)``' N for instant ``k``."""
    lines = []
    for k in range(epochs):
        tod = f"1235{first_second + k:02d}"
        lat = f"4807.{lat_milli(k):03d},N"
        lines += [
            _sentence(f"GPGGA,{tod},{lat},01131.000,E,1,08,0.9,545.4,M,46.9,M,,"),
            _sentence(f"GPRMC,{tod},A,{lat},01131.000,E,022.4,084.4,230394,003.1,W"),
        ]
    return lines


BANNER = "# GPSLogger 3.2 started 2026-11-23"


@pytest.mark.parametrize("banner", [[BANNER], [BANNER, "12", "Logger v3, serial 1234"]])
def test_nmea_after_a_banner_is_followed_with_one_warning(banner):
    clean: list[str] = []
    follow_lines(_nmea_lines(), clean.append)
    out: list[str] = []
    warned: list[str] = []
    counts = follow_lines([*banner, *_nmea_lines()], out.append, warn=warned.append)
    assert out == clean  # the banner changes nothing but the warning
    assert counts.skipped == len(banner)
    assert (counts.fixes, counts.invalid) == (5, 0)
    assert len(warned) == 1
    assert f"skipped {len(banner)} line" in warned[0]
    assert "before the first NMEA sentence" in warned[0]
    assert "neither NMEA nor a CSV header" in warned[0]


def test_clean_input_gives_no_warning(drive_csv):
    warned: list[str] = []
    for lines in (_nmea_lines(), drive_csv.splitlines()):
        counts = follow_lines(lines, [].append, warn=warned.append)
        assert counts.skipped == 0
    assert warned == []


@pytest.mark.parametrize("fmt", [None, "csv"])
def test_csv_after_a_banner_is_followed_with_one_warning(drive_csv, fmt):
    clean: list[str] = []
    follow_lines(drive_csv.splitlines(), clean.append, fmt=fmt)
    out: list[str] = []
    warned: list[str] = []
    counts = follow_lines(
        [BANNER, *drive_csv.splitlines()], out.append, fmt=fmt, warn=warned.append
    )
    assert out == clean
    assert counts.skipped == 1
    assert len(warned) == 1
    assert "skipped 1 line before the first CSV header" in warned[0]


def test_a_csv_without_a_usable_header_still_fails(drive_csv):
    """Banner skipping must not swallow a header-less or badly named CSV."""
    data = drive_csv.splitlines()[1:]  # no header: the first data row is taken as one
    with pytest.raises(InputError, match="cannot find the time column"):
        follow_lines(data, [].append)
    with pytest.raises(InputError, match="cannot find the time column"):
        follow_lines([BANNER, "when,y,x", *data], [].append)
    with pytest.raises(InputError, match="cannot find the time column"):
        follow_lines([BANNER], [].append)  # nothing but a banner


def test_cli_follow_file_with_a_banner(tmp_path):
    path = tmp_path / "drive.nmea"
    path.write_text("\n".join([BANNER, *_nmea_lines()]) + "\n")
    clean = tmp_path / "clean.nmea"
    clean.write_text("\n".join(_nmea_lines()) + "\n")
    result = CliRunner().invoke(main, ["detect", "--follow", str(path)])
    expected = CliRunner().invoke(main, ["detect", "--follow", str(clean)])
    assert result.exit_code == 0, result.output
    assert result.stdout == expected.stdout
    rows = _rows(result.stdout.splitlines())
    assert len(rows) == 10
    assert all(r["invalid_reason"] == "" for r in rows)
    warnings = [line for line in result.stderr.splitlines() if line.startswith("warning:")]
    assert len(warnings) == 1
    assert "skipped 1 line" in warnings[0]
    assert "GPSLogger" in warnings[0]
    assert "warning:" not in expected.stderr


def test_banner_on_a_live_pipe_does_not_hold_back_results():
    """A growing stream: the banner is skipped and the first instant's sentences answered
    as soon as their verdict is final (at once, or when the next instant's first sentence
    has come, where the shipped model settles each verdict with the next fix)."""
    lag = _lag()
    with _follow_stdin(subprocess.PIPE) as proc:
        assert proc.stdin is not None
        assert proc.stdout is not None
        assert proc.stderr is not None
        lines = _nmea_lines(2)
        try:
            proc.stdin.write(BANNER + "\n" + lines[0] + "\n")
            proc.stdin.flush()
            assert proc.stdout.readline().startswith("line,sentence,time")
            if not lag:
                assert proc.stdout.readline().startswith("1,GGA,")
            proc.stdin.write(lines[1] + "\n")
            proc.stdin.flush()
            if lag:
                proc.stdin.write(lines[2] + "\n")  # the next instant settles the first
                proc.stdin.flush()
                assert proc.stdout.readline().startswith("1,GGA,")
            assert proc.stdout.readline().startswith("2,RMC,")
        finally:
            proc.stdin.close()
            proc.stdout.read()
            err = proc.stderr.read()
            proc.wait(timeout=60)
    assert proc.returncode == 0
    assert sum(line.startswith("warning: skipped 1 line") for line in err.splitlines()) == 1


def _result_of(row: dict[str, str]) -> tuple[object, ...]:
    return tuple(row[c] for c in RESULT_FIELDS)


def _fields_of(result: object) -> tuple[object, ...]:
    from gradgps._run.follow import _result_fields

    return tuple(_result_fields(result))  # type: ignore[arg-type]


@pytest.fixture(scope="module")
def settling_model(tmp_path_factory: pytest.TempPathFactory) -> Path:
    from _gru_support import random_detector_model

    return random_detector_model(tmp_path_factory.mktemp("confirm"), confirm_head=True)


def _two_tracks() -> list[str]:
    """Two interleaved tracks with a jump, a gap (a new segment) and a bad line."""
    lines = ["track,time,lat,lon"]
    for i in range(60):
        t = i + (100 if i >= 40 else 0)  # a gap: the last fix before it keeps its verdict at once
        jump = 3e-3 if 20 <= i < 24 else 0.0
        lines += [f"a,{t},{48.0 + jump},{11 + i * 2e-4}", f"b,{i},{10.0 + i * 1e-4},20.0"]
        if i == 30:
            lines.append("b,not a time,10.0,20.0")
    return lines


def test_a_settling_model_writes_each_fix_once_its_verdict_is_final(settling_model):
    """With a confirm head each line goes out when its track's next fix has settled it,
    in input order: the lines equal a stream's final verdicts, fix for fix, and the
    counts count those."""
    lines = _two_tracks()
    out: list[str] = []
    counts = follow_lines(lines, out.append, model=settling_model)
    rows = _rows(out)
    assert [r["time"] for r in rows] == [line.split(",")[1] for line in lines[1:]]
    for track in ("a", "b"):
        mine = [r for r in rows if r["track"] == track and r["time"] != "not a time"]
        fixes = [(float(r["time"]), float(r["lat"]), float(r["lon"])) for r in mine]
        want = final_verdicts(Detector(settling_model), fixes)
        assert [_result_of(r) for r in mine] == [_fields_of(w) for w in want]
    named: list[str] = []
    follow_lines(lines, named.append, model=settling_model, fmt="csv")
    assert named == out
    assert counts.unsettled == 0
    assert counts.anomalies == sum(int(r["anomaly"]) for r in rows if not r["invalid_reason"])
    assert (counts.lines, counts.fixes, counts.invalid) == (len(rows), len(rows) - 1, 1)


def test_lines_held_too_long_go_out_with_their_verdict_at_once(settling_model, monkeypatch):
    """A track that stops sending holds the lines behind its last fix only up to
    HOLD_LINES lines: past that the oldest line goes out as it stands, counted."""
    import gradgps._run.follow as follow

    monkeypatch.setattr(follow, "HOLD_LINES", 3)
    lines = ["track,time,lat,lon", "a,0,48.0,11.0", "a,1,48.0,11.0002"]
    lines += [f"b,{i},10.0,{20 + i * 1e-4}" for i in range(10)]
    out: list[str] = []
    counts = follow_lines(lines, out.append, model=settling_model)
    rows = _rows(out)
    assert len(rows) == len(lines) - 1
    assert counts.unsettled == 1  # a's second fix: a never sent a third
    det = Detector(settling_model)
    det.update(0.0, 48.0, 11.0)
    assert _result_of(rows[1]) == _fields_of(det.update(1.0, 48.0, 11.0002))


def test_nmea_with_a_settling_model_repeats_the_settled_verdict_on_the_second_sentence(
    settling_model,
):
    lines = _nmea_lines(30, 0, lambda k: 38 + k * 11 + (300 if 12 <= k < 15 else 0))
    lines.insert(12, GSV)  # after the sixth instant
    out: list[str] = []
    counts = follow_lines(lines, out.append, model=settling_model)
    rows = _rows(out)
    assert [r["line"] for r in rows] == [str(i + 1) for i in range(len(lines))]
    scored = [r for r in rows if r["sentence"] == "GGA"]
    start = 12 * 3600 + 35 * 60
    fixes = [(start + k, float(r["lat"]), float(r["lon"])) for k, r in enumerate(scored)]
    want = final_verdicts(Detector(settling_model), fixes)
    assert [_result_of(r) for r in scored] == [_fields_of(w) for w in want]
    repeated = [r for r in rows if r["sentence"] == "RMC"]
    assert [_result_of(r) for r in repeated] == [_result_of(r) for r in scored]
    assert counts.fixes == 30
    assert counts.anomalies == sum(int(r["anomaly"]) for r in scored)


def _winding_csv(
    speed_factor: float = 1.0, minutes: float = 30.0, period_s: float = 1.0
) -> list[str]:
    """CSV lines of a simulated drive with its speed (times ``speed_factor``) and heading."""
    from gradgps._data.simulator import simulate_fleet

    drive = simulate_fleet(1, minutes, 1.0 / period_s, seed=21, imu=False)
    frame = drive[["t", "lat", "lon", "speed", "heading"]].copy()
    frame["speed"] *= speed_factor
    return frame.to_csv(index=False).splitlines()


def test_a_stream_says_each_input_warning_once_as_batch_would() -> None:
    """A km/h speed read as m/s: the checks batch runs on a whole file run on the stream
    too, and say so once, however many looks the stream gets; the same stream in m/s
    gets none."""
    from gradgps._run.follow import CHECK_EVERY

    lines = _winding_csv(3.6, minutes=80.0)
    assert len(lines) > 4 * CHECK_EVERY  # three looks before the end
    warned: list[str] = []
    out: list[str] = []
    follow_lines(lines, out.append, warn=warned.append)
    assert len(warned) == 1
    assert warned[0].startswith("reported speed (column 'speed', read in m/s)")
    assert "--speed-unit km/h" in warned[0]
    assert len(out) == len(lines)  # the lines themselves are what they were
    warned.clear()
    follow_lines(_winding_csv(1.0, minutes=80.0), [].append, warn=warned.append)
    assert warned == []


def test_a_short_stream_is_checked_at_its_end() -> None:
    """Fewer fixes than CHECK_EVERY: the checks look once, at the end of the input."""
    warned: list[str] = []
    lines = _winding_csv(1.0, minutes=8.0, period_s=5.0)
    follow_lines(lines, [].append, warn=warned.append)
    assert any("slower than the slowest rate the model was validated on" in w for w in warned)
    # What batch says of the same fixes, in the same words.
    from gradgps._tracks.input_checks import input_warnings
    from gradgps._tracks.track import to_fixes

    frame = pd.read_csv(io.StringIO("\n".join(lines)))
    assert warned == input_warnings(to_fixes(frame))


def test_follow_on_the_command_line_warns_on_stderr(tmp_path: Path) -> None:
    src = tmp_path / "kmh.csv"
    src.write_text("\n".join(_winding_csv(3.6, minutes=12.0)) + "\n")
    result = CliRunner().invoke(main, ["detect", "--follow", str(src)])
    assert result.exit_code == 0, result.output
    lines = [line for line in result.stderr.splitlines() if line.startswith("warning: ")]
    assert len(lines) == 1
    assert "--speed-unit km/h" in lines[0]
    assert "warning" not in result.stdout


def test_an_infinite_heading_in_a_stream_is_no_direction_to_the_checks_either() -> None:
    """The checks read a stream's headings as the batch reader does (modulo 360, an
    infinite one none), without a RuntimeWarning from the modulo."""
    lines = _winding_csv(1.0, minutes=12.0)
    header, *rows = lines
    rows[5] = ",".join([*rows[5].split(",")[:4], "inf"])
    warned: list[str] = []
    follow_lines([header, *rows], [].append, warn=warned.append)
    assert warned == []


@pytest.mark.parametrize("rewrite", ["newest first", "a second repeated"])
def test_a_stream_names_the_times_it_cannot_use_as_batch_does(rewrite: str) -> None:
    """Fixes the stream sets aside for their time (written newest first; one stamped with
    its predecessor's time at a new position) still go to the input checks, as batch gives
    them the whole file: the same warnings, in the same words (before: none, only the
    unusable lines' count)."""
    from gradgps._tracks.input_checks import input_warnings
    from gradgps._tracks.track import to_fixes

    frame = pd.read_csv(io.StringIO("\n".join(_winding_csv(1.0, minutes=5.0))))
    if rewrite == "newest first":
        frame = frame.iloc[::-1]
        kind = "time runs backwards"
    else:
        frame.loc[151:, "t"] -= 1.0
        kind = "repeated timestamps"
    lines = frame.to_csv(index=False).splitlines()
    warned: list[str] = []
    follow_lines(lines, [].append, warn=warned.append)
    assert [w for w in warned if w.startswith(kind)], warned
    assert warned == input_warnings(to_fixes(frame.reset_index(drop=True)))

"""NMEA 0183 reading: checksums, GGA+RMC merging, no-fix epochs, times, damaged logs."""

from __future__ import annotations

import calendar
import gzip
import math
from pathlib import Path

import numpy as np
import pynmea2
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from gradgps import InputError, to_fixes
from gradgps._io.nmea import KNOT_MS, MAX_NOTES, epoch_times, nmea_checksum, read_nmea
from gradgps._io.read import read_table

# The textbook examples (NMEA reference / gpsinformation.org), checksums as published.
GGA_REF = "$GPGGA,123519,4807.038,N,01131.000,E,1,08,0.9,545.4,M,46.9,M,,*47"
RMC_REF = "$GPRMC,123519,A,4807.038,N,01131.000,E,022.4,084.4,230394,003.1,W*6A"


def sentence(body: str) -> str:
    return f"${body}*{nmea_checksum(body):02X}"


def gga(
    time: str,
    lat: str = "4807.038,N",
    lon: str = "01131.000,E",
    quality: int = 1,
    talker: str = "GP",
) -> str:
    return sentence(f"{talker}GGA,{time},{lat},{lon},{quality},08,0.9,545.4,M,46.9,M,,")


def rmc(
    time: str,
    date: str = "230394",
    status: str = "A",
    talker: str = "GP",
    lat: str = "4807.038,N",
    lon: str = "01131.000,E",
) -> str:
    return sentence(f"{talker}RMC,{time},{status},{lat},{lon},022.4,084.4,{date},003.1,W")


def log(tmp_path: Path, lines: list[str], name: str = "l.nmea") -> Path:
    path = tmp_path / name
    path.write_text("\r\n".join(lines) + "\r\n", encoding="ascii")
    return path


def test_reference_checksums() -> None:
    assert f"{nmea_checksum(GGA_REF[1:-3]):02X}" == "47"
    assert f"{nmea_checksum(RMC_REF[1:-3]):02X}" == "6A"


def test_gga_and_rmc_of_one_epoch_merge(tmp_path: Path) -> None:
    table = read_nmea(log(tmp_path, [RMC_REF, GGA_REF]))
    assert table.rejected == 0
    row = table.frame.iloc[0]
    assert len(table.frame) == 1
    assert row["lat"] == pytest.approx(48 + 7.038 / 60, abs=1e-12)
    assert row["lon"] == pytest.approx(11 + 31.0 / 60, abs=1e-12)
    assert row["alt"] == 545.4
    assert row["hdop"] == 0.9
    assert row["satellites"] == 8
    assert row["fix_quality"] == 1
    assert row["speed"] == pytest.approx(22.4 * 0.514444, rel=1e-5)
    assert row["course"] == 84.4
    assert table.times is not None
    assert table.times[0] == calendar.timegm((1994, 3, 23, 12, 35, 19))
    assert row["time"] == "1994-03-23T12:35:19Z"  # the form every mode writes (issue 14)
    assert row["line"] == 1
    fixes = to_fixes(table)
    assert fixes["heading"].iloc[0] == 84.4
    assert fixes["track"].iloc[0] == "0"


def test_three_bad_checksums_are_counted_not_fatal(tmp_path: Path) -> None:
    lines = []
    for second in range(10):
        lines += [rmc(f"1235{second:02d}"), gga(f"1235{second:02d}")]
    lines[3] = lines[3].replace("4807.038", "4807.039")  # data changed, checksum kept
    lines[8] = lines[8][:-2] + ("00" if lines[8][-2:] != "00" else "01")
    lines[15] = lines[15].replace("545.4", "5X5.4")
    path = log(tmp_path, lines)
    table = read_table(path)
    assert table.rejected == 3
    assert table.notes is not None
    assert [n.split(":")[0] for n in table.notes] == ["line 4", "line 9", "line 16"]
    assert all("checksum mismatch" in n for n in table.notes)
    assert len(table.frame) == 10  # every epoch still has its other sentence
    assert table.frame["lat"].notna().all()


def test_unknown_sentences_and_text_are_skipped_not_counted(tmp_path: Path) -> None:
    lines = [
        "garbage without a dollar",
        "$GPGSV,3,1,11,03,03,111,00,04,15,270,00,06,01,010,00,13,06,292,00*ZZ",  # bad, but not used
        sentence("PUBX,00,081350.00,4717.113210,N"),
        "2019-05-23 20:54:11 " + GGA_REF,  # a logger's prefix
        "",
    ]
    table = read_nmea(log(tmp_path, lines))
    assert (table.rejected, len(table.frame)) == (0, 1)
    assert table.frame["line"].tolist() == [4]


@pytest.mark.parametrize(
    ("line", "reason"),
    [
        (GGA_REF[:-3], "no checksum"),
        (GGA_REF[:30], "no checksum"),
        (GGA_REF[:-2] + "4", "checksum is not two hex digits"),
        (gga("123519", lat="4861.000,N"), "minutes of 60 or more"),
        (gga("123519", lat="4807.038,X"), "hemisphere must be N or S"),
        (gga("123519", lon="18100.000,E"), "beyond 180 degrees"),
        (gga("126019"), "impossible time of day"),
        (rmc("123519", date="310294"), "impossible date"),
        (rmc("123519", status="Q"), "status must be A or V"),
        (sentence("GPGGA,123519,4807.038,N"), "GGA has 3 fields"),
        (
            sentence("GPRMC,123519,A,4807.038,N,01131.000,E,abc,084.4,230394,,"),
            "speed is not a number",
        ),
    ],
)
def test_malformed_sentences_are_rejected_with_reason(
    tmp_path: Path, line: str, reason: str
) -> None:
    table = read_nmea(log(tmp_path, [gga("123518"), line]))
    assert table.rejected == 1
    assert table.notes is not None
    assert table.notes[0].startswith("line 2: ")
    assert reason in table.notes[0]
    assert len(table.frame) == 1


def test_any_talker(tmp_path: Path) -> None:
    lines = [
        rmc("000001", talker="GN"),
        gga("000001", talker="GN"),
        gga("000002", talker="GL"),
        gga("000003", talker="GA"),
        gga("000004", talker="BD"),
    ]
    assert len(read_nmea(log(tmp_path, lines)).frame) == 4


def test_no_fix_epochs_keep_their_row_with_missing_position(tmp_path: Path) -> None:
    lines = [
        sentence("GPGGA,,,,,,0,00,99.99,,,,,,"),  # u-blox before the first fix
        rmc("120000", status="V"),
        gga("120000", quality=0),
        rmc("120001"),
        gga("120001", quality=0),  # receivers disagree: no fix wins
        rmc("120002"),
        gga("120002"),
    ]
    table = read_nmea(log(tmp_path, lines))
    frame = table.frame
    assert len(frame) == 4
    assert frame["lat"].isna().tolist() == [True, True, True, False]
    assert table.times is not None
    assert math.isnan(table.times[0])
    assert frame["time"].iloc[0] == ""
    assert frame["fix_quality"].tolist() == [0, 0, 0, 1]


def test_times_without_date_roll_over_midnight(tmp_path: Path) -> None:
    table = read_nmea(log(tmp_path, [gga("235959"), gga("000000"), gga("000000.5"), gga("000001")]))
    assert table.times is not None
    assert table.times.tolist() == [86399.0, 86400.0, 86400.5, 86401.0]
    assert table.frame["time"].tolist() == ["23:59:59Z", "00:00:00Z", "00:00:00.500Z", "00:00:01Z"]
    assert table.notes == ["no RMC date in the log: times are times of day (UTC), without a date"]
    assert "speed" not in table.frame.columns
    assert table.columns.speed == ""


def test_dates_carry_to_undated_epochs_and_across_midnight(tmp_path: Path) -> None:
    lines = [
        gga("235958"),
        rmc("235959", date="311219"),
        gga("235959"),
        gga("000000"),
        rmc("000001", date="010120"),
    ]
    times = read_nmea(log(tmp_path, lines)).times
    assert times is not None
    midnight = calendar.timegm((2020, 1, 1, 0, 0, 0))
    assert times.tolist() == [midnight - 2.0, midnight - 1.0, midnight, midnight + 1.0]


@pytest.mark.parametrize(
    "dates",
    [
        # The first RMC after midnight still names the day that ended (issue 18).
        ("311219", "311219", "311219", "010120", "010120"),
        # ... and the GGA-only epochs after it take that stale date.
        ("", "311219", "311219", "", "010120"),
        # Stale for every dated epoch the log has after midnight.
        ("", "311219", "311219", "311219", ""),
        # No dated epoch before midnight: the next one says the day is new.
        ("", "", "311219", "010120", ""),
    ],
)
def test_stale_rmc_date_at_midnight_does_not_send_fixes_back_a_day(
    tmp_path: Path, dates: tuple[str, ...]
) -> None:
    times = ("235958", "235959", "000000", "000001", "000002")
    lines = [rmc(t, date=d) if d else gga(t) for t, d in zip(times, dates, strict=True)]
    table = read_nmea(log(tmp_path, lines))
    assert table.times is not None
    midnight = calendar.timegm((2020, 1, 1, 0, 0, 0))
    assert table.times.tolist() == [midnight + s for s in (-2.0, -1.0, 0.0, 1.0, 2.0)]
    assert table.frame["time"].iloc[2] == "2020-01-01T00:00:00Z"


def test_a_day_behind_later_in_the_day_is_believed() -> None:
    # Not a stale date: a log that really goes back a day keeps what it says.
    day = 1e9 - 1e9 % 86400
    tod = np.array([86000.0, 5 * 3600.0])
    times = epoch_times(tod, np.array([day, day]))
    np.testing.assert_array_equal(times, [day + 86000.0, day + 5 * 3600.0])


def test_epoch_times_reference() -> None:
    tod = np.array([86000.0, np.nan, 100.0, 50.0, 200.0])
    midnight = np.array([np.nan, np.nan, np.nan, 1e9, np.nan])
    # 50 after 100 is a small step back (out-of-order fix), not a new day.
    np.testing.assert_array_equal(
        epoch_times(tod, np.full(5, np.nan)), [86000.0, np.nan, 86500.0, 86450.0, 86600.0]
    )
    np.testing.assert_array_equal(
        epoch_times(tod, midnight), [1e9 - 400.0, np.nan, 1e9 + 100.0, 1e9 + 50.0, 1e9 + 200.0]
    )


def test_notes_are_capped(tmp_path: Path) -> None:
    lines = [RMC_REF] + [GGA_REF[:-2] + "00"] * (MAX_NOTES + 5)
    table = read_nmea(log(tmp_path, lines))
    assert table.rejected == MAX_NOTES + 5
    assert table.notes is not None
    assert len(table.notes) == MAX_NOTES + 1
    assert table.notes[-1] == "... and 5 more rejected sentences"


@pytest.mark.parametrize(
    ("content", "match"),
    [
        (b"", "empty file"),
        (b"$GPTXT,banner\nhello\n", "no usable GGA or RMC sentences in 2 lines"),
        ((GGA_REF[:-2] + "00\n").encode() * 3, r"3 rejected, first: line 1: GGA checksum mismatch"),
        (
            np.random.default_rng(2).integers(0, 256, 4096, dtype=np.uint8).tobytes(),
            "no usable GGA or RMC",
        ),
    ],
    ids=["empty", "not-nmea", "all-rejected", "binary-garbage"],
)
def test_unusable_logs(tmp_path: Path, content: bytes, match: str) -> None:
    path = tmp_path / "x.nmea"
    path.write_bytes(content)
    with pytest.raises(InputError, match=match):
        read_table(path)


def test_noise_bytes_inside_a_sentence_only_reject_it(tmp_path: Path) -> None:
    path = tmp_path / "noisy.nmea"
    path.write_bytes(
        GGA_REF.encode() + b"\n" + GGA_REF.replace("4807", "48\xff7").encode("latin-1") + b"\n"
    )
    table = read_table(path)
    assert (len(table.frame), table.rejected) == (1, 1)


def test_truncated_log_and_gzip(tmp_path: Path) -> None:
    text = "\n".join([RMC_REF, GGA_REF, RMC_REF.replace("123519", "123520")[:40]])
    path = tmp_path / "cut.nmea.gz"
    path.write_bytes(gzip.compress(text.encode()))
    table = read_table(path)
    assert (len(table.frame), table.rejected) == (1, 1)
    assert table.notes is not None
    assert "no checksum" in table.notes[0]


@settings(max_examples=60, deadline=None)
@given(
    lat=st.floats(-89.99, 89.99),
    lon=st.floats(-179.99, 179.99),
    knots=st.floats(0, 200),
    course=st.floats(0, 359.9),
)
def test_agrees_with_pynmea2(
    tmp_path_factory: pytest.TempPathFactory, lat: float, lon: float, knots: float, course: float
) -> None:
    def ddmm(value: float, width: int) -> str:
        deg = int(abs(value))
        return f"{deg:0{width}d}{(abs(value) - deg) * 60:07.4f}"

    body = (
        f"GNRMC,101112.20,A,{ddmm(lat, 2)},{'N' if lat >= 0 else 'S'},{ddmm(lon, 3)},"
        f"{'E' if lon >= 0 else 'W'},{knots:.3f},{course:.2f},150624,,,A"
    )
    line = sentence(body)
    path = tmp_path_factory.mktemp("nmea") / "one.nmea"
    path.write_text(line + "\n")
    table = read_nmea(path)
    ours = table.frame.iloc[0]
    theirs = pynmea2.parse(line)
    assert ours["lat"] == pytest.approx(theirs.latitude, abs=1e-12)
    assert ours["lon"] == pytest.approx(theirs.longitude, abs=1e-12)
    assert ours["speed"] == pytest.approx(theirs.spd_over_grnd * KNOT_MS, rel=1e-12)
    assert ours["course"] == pytest.approx(theirs.true_course)
    assert table.times is not None
    assert table.times[0] == calendar.timegm((2024, 6, 15, 10, 11, 12)) + 0.2

"""The receiver's own fix quality, satellite count and HDOP: read by every reader, and a fix
the receiver reports as no fix flagged the same way in every mode without touching the state."""

from __future__ import annotations

import io
import json
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd
import pytest
from click.testing import CliRunner

from gradgps import read_table, to_fixes
from gradgps._cli import main
from gradgps._data.simulator import simulate_fleet
from gradgps._grad.detector import Detector, MultiTrackDetector
from gradgps._io.nmea import nmea_checksum, read_nmea
from gradgps._result import NO_FIX, NO_SATELLITES, fix_quality_code, fix_reason, invalid_reasons
from gradgps._run.follow import follow_lines
from gradgps._tracks.track import ColumnMap, resolve_columns

COLUMNS = ["anomaly", "score", "bias_type", "time_type", "lat_clean", "lon_clean", "alert"]


def _drive(n: int = 160, seed: int = 4) -> pd.DataFrame:
    fleet = simulate_fleet(1, n / 60.0, 1.0, seed=seed)
    return fleet[["t", "lat", "lon", "speed", "heading"]].reset_index(drop=True)


def _with_receiver(frame: pd.DataFrame) -> tuple[pd.DataFrame, np.ndarray]:
    """``frame`` with fix_quality/satellites/hdop columns; some rows the receiver calls no fix."""
    out = frame.copy()
    n = len(out)
    out["fix_quality"] = 1
    out["sats"] = 9
    out["hdop"] = 0.9
    no_fix_q = np.array([20, 21, 22, 70, 71])
    no_fix_s = np.array([100, 130])
    out.loc[no_fix_q, "fix_quality"] = 0
    out.loc[no_fix_q, "hdop"] = 99.99
    out.loc[no_fix_s, "sats"] = 0
    bad = np.zeros(n, dtype=bool)
    bad[no_fix_q] = True
    bad[no_fix_s] = True
    return out, bad


def _same(a: pd.DataFrame, b: pd.DataFrame) -> None:
    for c in COLUMNS:
        x, y = a[c].reset_index(drop=True), b[c].reset_index(drop=True)
        if c in ("bias_type", "time_type"):
            assert x.fillna("").astype(str).tolist() == y.fillna("").astype(str).tolist(), c
        else:
            np.testing.assert_array_equal(x.to_numpy(float), y.to_numpy(float), err_msg=c)
    np.testing.assert_array_equal(
        a["invalid_reason"].fillna("").astype(str), b["invalid_reason"].fillna("").astype(str)
    )


# ------------------------------------------------------------------ reading values


@pytest.mark.parametrize(
    ("value", "code"),
    [
        (0, 0.0),
        ("0", 0.0),
        ("V", 0.0),
        ("none", 0.0),
        ("No Fix", 0.0),
        ("A", 1.0),
        ("3d", 1.0),
        ("dgps", 2.0),
        (4, 4.0),
        ("RTK-float", 5.0),
        ("", np.nan),
        (None, np.nan),
        ("garbage", np.nan),
        (float("inf"), np.nan),
    ],
)
def test_fix_quality_values(value: object, code: float) -> None:
    got = fix_quality_code(value)
    assert (np.isnan(got) and np.isnan(code)) or got == code


def test_fix_reason_names_the_receiver_and_time_still_comes_first() -> None:
    assert fix_reason(1.0, 52.0, 13.0, fix_quality=0) == NO_FIX
    assert fix_reason(1.0, np.nan, np.nan, fix_quality="V") == NO_FIX
    assert fix_reason(1.0, 52.0, 13.0, satellites=0) == NO_SATELLITES
    assert fix_reason(np.nan, 52.0, 13.0, fix_quality=0) == "time missing or not finite"
    assert fix_reason(1.0, 52.0, 13.0, fix_quality=1, satellites=7) == ""
    assert fix_reason(1.0, 52.0, 13.0, fix_quality="junk", satellites="x") == ""


@pytest.mark.parametrize(
    ("fix_col", "sats_col"),
    [("fix_quality", "satellites"), ("quality", "sats"), ("fix", "num_sats"), ("Fix", "NumSats")],
)
def test_common_column_names_are_found(fix_col: str, sats_col: str) -> None:
    cmap = resolve_columns(["t", "lat", "lon", fix_col, sats_col, "hdop"])
    assert (cmap.fix_quality, cmap.satellites, cmap.hdop) == (fix_col, sats_col, "hdop")


def test_csv_and_parquet_carry_the_receiver_columns(tmp_path: Path) -> None:
    frame = pd.DataFrame(
        {
            "t": [0.0, 1.0, 2.0, 3.0],
            "lat": [52.0, 52.0001, 52.0002, 0.0],
            "lon": [13.0, 13.0, 13.0, 0.0],
            "status": ["A", "V", "A", "V"],
            "num_sats": [8, 8, 0, 0],
            "hdop": [1.0, 99.0, 1.0, 99.0],
        }
    )
    for path in (tmp_path / "a.csv", tmp_path / "a.parquet"):
        if path.suffix == ".csv":
            frame.to_csv(path, index=False)
        else:
            frame.to_parquet(path)
        fixes = to_fixes(read_table(path), ColumnMap(fix_quality="status"))
        np.testing.assert_array_equal(fixes["fix_quality"], [1.0, 0.0, 1.0, 0.0])
        np.testing.assert_array_equal(fixes["satellites"], [8.0, 8.0, 0.0, 0.0])
        np.testing.assert_array_equal(fixes["hdop"], [1.0, 99.0, 1.0, 99.0])
        # The receiver's verdict explains even a (0, 0) position.
        assert list(invalid_reasons(fixes)) == ["", NO_FIX, NO_SATELLITES, NO_FIX]


def _sentence(body: str) -> str:
    return f"${body}*{nmea_checksum(body):02X}"


def _nmea_log(tmp_path: Path) -> Path:
    lines = []
    for k in range(12):
        hhmmss = f"1000{k:02d}"
        quality = 0 if k in (4, 5) else 1
        sats = "00" if k == 8 else "09"
        gga = _sentence(
            f"GPGGA,{hhmmss}.00,4807.{k:03d},N,01131.000,E,{quality},{sats},0.9,545.4,M,,M,,"
        )
        status = "V" if k == 10 else "A"
        rmc = _sentence(f"GPRMC,{hhmmss}.00,{status},4807.{k:03d},N,01131.000,E,22.4,84.4,231126,,")
        # Epoch 10 starts with its RMC (status V), as some receivers order them.
        lines += [rmc, gga] if k == 10 else [gga, rmc]
    path = tmp_path / "log.nmea"
    path.write_text("\n".join(lines) + "\n")
    return path


def test_nmea_gga_quality_rmc_status_and_satellites(tmp_path: Path) -> None:
    table = read_nmea(_nmea_log(tmp_path))
    assert table.frame["fix_quality"].tolist() == [1, 1, 1, 1, 0, 0, 1, 1, 1, 1, 0, 1]
    assert table.frame["satellites"].tolist()[8] == 0
    reasons = invalid_reasons(to_fixes(table))
    assert [i for i, r in enumerate(reasons) if r] == [4, 5, 8, 10]
    assert reasons[4] == reasons[10] == NO_FIX
    assert reasons[8] == NO_SATELLITES


def test_gpx_fix_and_sat(tmp_path: Path) -> None:
    points = []
    for k in range(6):
        fix = {1: "<fix>none</fix>", 2: "<fix>3d</fix>", 3: "<fix>dgps</fix>"}.get(k, "")
        sat = "<sat>0</sat>" if k == 4 else "<sat>7</sat>"
        points.append(
            f'<trkpt lat="52.{k:04d}" lon="13.0"><time>2026-11-23T10:00:0{k}Z</time>'
            f"{fix}{sat}<hdop>1.2</hdop></trkpt>"
        )
    path = tmp_path / "a.gpx"
    path.write_text(
        '<?xml version="1.0"?><gpx version="1.1" xmlns="http://www.topografix.com/GPX/1/1">'
        f"<trk><trkseg>{''.join(points)}</trkseg></trk></gpx>"
    )
    table = read_table(path)
    assert table.frame["fix"].tolist() == ["", "none", "3d", "dgps", "", ""]
    fixes = to_fixes(table)
    np.testing.assert_array_equal(fixes["fix_quality"], [np.nan, 0.0, 1.0, 2.0, np.nan, np.nan])
    np.testing.assert_array_equal(fixes["satellites"], [7, 7, 7, 7, 0, 7])
    assert list(invalid_reasons(fixes)) == ["", NO_FIX, "", "", NO_SATELLITES, ""]


# ------------------------------------------------------------- one answer, no state touched


def test_no_fix_rows_are_flagged_and_never_touch_the_detector_state() -> None:
    frame, bad = _with_receiver(_drive())
    result = Detector().detect(frame)
    assert (result.loc[bad, "anomaly"] == 1).all()
    assert set(result.loc[bad, "invalid_reason"]) == {NO_FIX, NO_SATELLITES}
    assert result.loc[bad, "lat_clean"].isna().all()
    # The other rows get exactly what they get when the no-fix rows are not there at all.
    alone = Detector().detect(frame[~bad].drop(columns=["fix_quality", "sats", "hdop"]))
    _same(result[~bad], alone)


def test_files_that_report_a_fix_everywhere_behave_as_files_without_the_fields() -> None:
    frame = _drive()
    reported = frame.assign(fix_quality=1, sats=9, hdop=0.9)
    _same(Detector().detect(reported), Detector().detect(frame))


def test_update_keyword_flags_and_keeps_the_state() -> None:
    frame = _drive(40)
    det = Detector()
    for r in frame.iloc[:20].itertuples():
        det.update(r.t, r.lat, r.lon, r.speed, r.heading, fix_quality=1, satellites=9)
    before = json.dumps(det.get_state())
    r = frame.iloc[20]
    for kwargs in ({"fix_quality": 0}, {"fix_quality": "V"}, {"satellites": 0}):
        res = det.update(r.t, r.lat, r.lon, r.speed, r.heading, **kwargs)
        assert res.anomaly == 1
        assert res.invalid_reason in (NO_FIX, NO_SATELLITES)
        assert json.dumps(det.get_state()) == before
    assert det.update(r.t, r.lat, r.lon, r.speed, r.heading, fix_quality="3d").invalid_reason == ""


def _redis_results(frame: pd.DataFrame) -> pd.DataFrame:
    fakeredis = pytest.importorskip("fakeredis")
    pytest.importorskip("lupa")
    from gradgps._run.fleet_redis import RedisStreamWorker, parse_output

    server = fakeredis.FakeServer()

    def client() -> Any:
        return fakeredis.FakeRedis(server=server, decode_responses=True)

    worker = RedisStreamWorker(client(), "in", "out", "g", "w1", batch_size=64)
    worker.ensure_group()
    push = client()
    for r in frame.itertuples():
        push.xadd(
            "in",
            {
                "vehicle_id": "car",
                "t": repr(r.t),
                "lat": repr(r.lat),
                "lon": repr(r.lon),
                "speed": repr(r.speed),
                "heading": repr(r.heading),
                "fix_quality": str(r.fix_quality),
                "satellites": str(r.sats),
            },
        )
    for _ in range(50):
        report = worker.step()
        if not (report.routed_here or report.processed or report.taken_over):
            break
    return pd.DataFrame([parse_output(f) for _, f in client().xrange("out")])


def test_every_mode_gives_one_answer(tmp_path: Path) -> None:
    frame, bad = _with_receiver(_drive())
    source = tmp_path / "drive.csv"
    frame.to_csv(source, index=False)
    outs = {}
    for name, extra in (("chunked", ["--chunk-size", "37"]), ("largest", ["--chunk-size", "0"])):
        out = tmp_path / f"{name}.csv"
        res = CliRunner().invoke(main, ["detect", str(source), "-o", str(out), *extra])
        assert res.exit_code == 0, res.output
        outs[name] = pd.read_csv(out, keep_default_na=False, na_values=[""])
    python = Detector().detect(pd.read_csv(source))
    streamed = MultiTrackDetector().update_fixes(to_fixes(pd.read_csv(source)))
    lines: list[str] = []
    with source.open() as f:
        follow_lines(f, lines.append)
    followed = pd.read_csv(io.StringIO("\n".join(lines)), keep_default_na=False, na_values=[""])
    base = outs["chunked"]
    assert (base.loc[bad, "invalid_reason"] != "").all()
    assert (base.loc[~bad, "invalid_reason"].fillna("") == "").all()
    for other in (outs["largest"], python, streamed, followed):
        _same(base, other)
    redis = _redis_results(frame)
    assert redis["invalid_reason"].fillna("").tolist() == base["invalid_reason"].fillna("").tolist()
    np.testing.assert_array_equal(redis["anomaly"].astype(int), base["anomaly"])


def test_follow_nmea_flags_what_the_batch_reader_flags(tmp_path: Path) -> None:
    path = _nmea_log(tmp_path)
    batch = Detector().detect(to_fixes(read_nmea(path)))
    lines: list[str] = []
    with path.open() as f:
        follow_lines(f, lines.append)
    followed = pd.read_csv(io.StringIO("\n".join(lines)), keep_default_na=False, na_values=[""])
    # The first sentence of each epoch is scored, the second repeats its verdict.
    scored = followed[followed["line"] == followed["epoch_line"]].reset_index(drop=True)
    assert len(scored) == len(batch)
    assert scored["invalid_reason"].fillna("").tolist() == batch["invalid_reason"].tolist()
    assert batch.loc[10, "invalid_reason"] == NO_FIX
    # (Scores differ: a GGA-first epoch is scored in a stream before its RMC speed arrives.)
    np.testing.assert_array_equal(scored["anomaly"].iloc[[4, 5, 8, 10]], 1)

"""One answer in every mode: chunked, the largest chunks (``--chunk-size 0``), report,
follow, Python on the whole file, for repeated, equal and backward timestamps; invalid
rows counted the same everywhere."""

from __future__ import annotations

import io
import re
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from click.testing import CliRunner

import gradgps
from gradgps._cli import main
from gradgps._data.inject import inject_grad
from gradgps._data.simulator import simulate_fleet
from gradgps._grad.detector import Detector, TrackStreams
from gradgps._run.follow import follow_lines
from gradgps._tracks.track import to_fixes

# Odd inputs on purpose: the Detector says so (gradgps.InputWarning); what is tested here
# is the answer it gives all the same.
pytestmark = pytest.mark.filterwarnings("ignore::gradgps.InputWarning")

COLUMNS = ["anomaly", "bias_type", "time_type", "alert", "invalid_reason"]


def _logger_file(tmp_path: Path) -> Path:
    """Two tracks at 10 Hz written with whole-second times (9 of 10 rows repeat a time),
    plus a swapped pair and a backward jump."""
    drives = inject_grad(simulate_fleet(2, 2.0, 10.0, seed=5), seed=2)
    frame = drives[["track", "t", "lat", "lon", "speed", "heading"]].copy()
    frame["t"] = np.floor(frame["t"]).astype(np.int64)
    frame = frame.reset_index(drop=True)
    first = frame.index[frame["track"] == "0"][0]
    a, b = first + 25, first + 45  # a swapped pair of distinct times
    frame.loc[[a, b]] = frame.loc[[b, a]].to_numpy()
    frame.loc[first + 300, "t"] -= 7  # a backward jump
    path = tmp_path / "logger.csv"
    frame.to_csv(path, index=False)
    return path


def _same(a: pd.DataFrame, b: pd.DataFrame) -> None:
    for c in COLUMNS:
        assert a[c].fillna("").astype(str).tolist() == b[c].fillna("").astype(str).tolist(), c
    for c in ("score", "lat_clean", "lon_clean"):
        np.testing.assert_array_equal(a[c].to_numpy(float), b[c].to_numpy(float), err_msg=c)


def _cli(args: list[str]) -> str:
    result = CliRunner().invoke(main, args)
    assert result.exit_code == 0, result.output
    return str(result.output)


def test_repeated_equal_and_backward_times_give_one_answer_in_every_mode(tmp_path: Path) -> None:
    source = _logger_file(tmp_path)
    outs = {}
    for name, extra in (
        ("chunked", ["--chunk-size", "997"]),
        ("largest", ["--chunk-size", "0"]),
        ("report", ["--report", str(tmp_path / "r.html")]),
        ("report_largest", ["--chunk-size", "0", "--report", str(tmp_path / "r2.html")]),
    ):
        out = tmp_path / f"{name}.csv"
        _cli(["detect", str(source), "-o", str(out), *extra])
        outs[name] = pd.read_csv(out, keep_default_na=False, na_values=[""])
    frame = pd.read_csv(source)
    python = Detector().detect(frame)
    streamed = TrackStreams().update_fixes(to_fixes(frame))
    lines: list[str] = []
    with source.open() as f:
        follow_lines(f, lines.append)
    followed = pd.read_csv(io.StringIO("\n".join(lines)), keep_default_na=False, na_values=[""])
    base = outs["chunked"]
    for other in (*outs.values(), python, streamed, followed):
        _same(base, other.reset_index(drop=True))
    reasons = base["invalid_reason"].fillna("")
    # 9 of 10 rows repeat a time: unusable, flagged with the reason, never averaged.
    repeated = (reasons == "time not after the previous fix").sum()
    assert repeated >= 0.85 * len(base)
    assert base.loc[reasons != "", "lat_clean"].isna().all()
    # No invented position: every usable row's clean position is its own or a repair of it,
    # never a mean of rows sharing its time (the old batch path averaged them).
    usable = base[reasons == ""]
    assert usable["t"].is_unique or usable.groupby("track")["t"].apply(lambda s: s.is_unique).all()


def test_report_does_not_change_the_answer_for_a_swapped_pair(tmp_path: Path) -> None:
    drives = simulate_fleet(1, 2.0, 1.0, seed=3)[["t", "lat", "lon"]].reset_index(drop=True)
    drives.loc[[10, 11]] = drives.loc[[11, 10]].to_numpy()
    source = tmp_path / "swapped.csv"
    drives.to_csv(source, index=False)
    plain, with_report = tmp_path / "a.csv", tmp_path / "b.csv"
    _cli(["detect", str(source), "-o", str(plain)])
    _cli(["detect", str(source), "-o", str(with_report), "--report", str(tmp_path / "r.html")])
    a, b = pd.read_csv(plain), pd.read_csv(with_report)
    assert a["invalid_reason"].fillna("").tolist()[11] == "time not after the previous fix"
    _same(a, b)


def test_report_is_written_atomically(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    from gradgps._run import report as report_module

    drives = simulate_fleet(1, 1.0, 1.0, seed=3)
    fixes = to_fixes(drives)
    det = Detector()
    inputs = report_module.ReportInputs(
        fixes=fixes, result=det.detect(fixes), params=det.model_.params
    )
    target = tmp_path / "report.html"
    target.write_text("the previous report")

    def half_then_disk_full(self: Path, data: object, *args: object, **kwargs: object) -> int:
        text = data if isinstance(data, str) else bytes(data).decode()  # type: ignore[call-overload]
        with open(self, "w", encoding="utf-8") as f:
            f.write(text[: len(text) // 2])
        raise OSError(28, "No space left on device")

    monkeypatch.setattr(Path, "write_text", half_then_disk_full)
    monkeypatch.setattr(Path, "write_bytes", half_then_disk_full)
    with pytest.raises(OSError, match="No space"):
        report_module.write_report(inputs, target)
    monkeypatch.undo()
    assert target.read_text() == "the previous report"
    assert [p.name for p in tmp_path.iterdir()] == ["report.html"]


def test_invalid_rows_are_counted_the_same_in_cli_csv_report_and_info(tmp_path: Path) -> None:
    source = _logger_file(tmp_path)
    out, report = tmp_path / "out.csv", tmp_path / "r.html"
    said = _cli(["detect", str(source), "-o", str(out), "--report", str(report)])
    csv = pd.read_csv(out, keep_default_na=False)
    anomalies = int(csv["anomaly"].sum())
    invalid = int((csv["invalid_reason"] != "").sum())
    assert invalid > 0
    assert f"{anomalies:,} anomalies ({invalid:,} invalid fixes)" in said.replace("\n", " ")
    text = report.read_text()
    summary = re.search(r"anomalies \(anomaly=1 in the CSV\)</td><td>([\d,]+) ", text)
    assert summary is not None
    assert int(summary.group(1).replace(",", "")) == anomalies
    assert f"{invalid:,} invalid fixes" in text
    assert f"invalid rows: {invalid:,}" in _cli(["info", str(source)])


def test_all_points_at_one_time_do_not_collapse_onto_the_centroid() -> None:
    drive = simulate_fleet(1, 2.0, 1.0, seed=8)[["lat", "lon"]].reset_index(drop=True)
    drive["time"] = "2026-11-23T10:00:00Z"
    out = gradgps.detect(drive)
    assert out["invalid_reason"].iloc[0] == ""
    assert (out["invalid_reason"].iloc[1:] == "time not after the previous fix").all()
    assert out["lat_clean"].iloc[1:].isna().all()  # no averaged position anywhere


def test_detect_keeps_the_callers_index() -> None:
    drive = simulate_fleet(1, 1.0, 1.0, seed=2)[["t", "lat", "lon"]].reset_index(drop=True)
    drive.index = drive.index * 2  # 0, 2, 4, ...
    result = Detector().detect(drive)
    assert list(result.index) == list(drive.index)
    joined = drive.join(result)
    assert joined["invalid_reason"].notna().all()
    assert joined["lat_clean"].notna().all()


def test_update_takes_timestamps_and_iso_strings() -> None:
    a, b = Detector(), Detector()
    for k in range(5):
        when = pd.Timestamp("2026-11-23T10:00:00Z") + pd.Timedelta(seconds=k)
        r1 = a.update(when, 41.0 + k * 1e-4, -96.0)
        r2 = b.update(when.isoformat(), 41.0 + k * 1e-4, -96.0)
        assert r1.invalid_reason == ""
        assert r1 == r2

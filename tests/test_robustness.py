"""The robustness suite (``gradgps bench --suite robustness``): decimation, verdicts, shape."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from click.testing import CliRunner

from _robustness_support import write_tiny_new_drives
from gradgps import ConfigError, Detector
from gradgps._cli import main
from gradgps._eval.robustness import (
    RATES,
    ROBUSTNESS_DATASETS,
    decimate,
    evident_holds,
    judge,
    robustness_markdown,
    run_robustness,
)
from gradgps._tracks.track import ColumnMap
from test_bench_all import _tiny_data

CMAP = ColumnMap(time="t", lat="lat", lon="lon", track="track")


def _table(t: list[float], track: str = "a") -> pd.DataFrame:
    n = len(t)
    return pd.DataFrame({"track": track, "t": t, "lat": np.linspace(52, 52.01, n), "lon": 4.4})


def test_decimation_keeps_a_fix_once_a_period_has_passed() -> None:
    table = pd.concat(
        [_table([0, 1, 2, 3, 4, 5, 6]), _table([10.0, 10.5, 11.0, 11.999, 13.5], "b")]
    ).reset_index(drop=True)
    out = decimate(table, CMAP, 2.0)
    # b: 10.5 and 11.0 are too close to 10; 11.999 is within the 1 ms slack; 13.5 too close.
    assert out["t"].tolist() == [0, 2, 4, 6, 10.0, 11.999]
    one_hz = decimate(table, CMAP, 1.0)["t"].tolist()
    assert one_hz == [0, 1, 2, 3, 4, 5, 6, 10.0, 11.0, 11.999, 13.5]
    assert list(out.index) == list(range(len(out)))
    assert list(out.columns) == list(table.columns)


def test_decimation_is_per_track_in_time_order_and_keeps_input_order() -> None:
    table = pd.DataFrame(
        {
            "track": ["a", "b", "a", "b", "a", "a"],
            "t": [2.0, 0.0, 0.0, 1.0, 1.0, np.nan],
            "lat": 52.0,
            "lon": 4.4,
        }
    )
    out = decimate(table, CMAP, 2.0)
    # a: 0 and 2 kept (1 is too close), no time: dropped; b: 0 kept, 1 too close.
    assert out[["track", "t"]].values.tolist() == [["a", 2.0], ["b", 0.0], ["a", 0.0]]


def _cell(
    fa: float, f1: float, nr: float, rec: float, cor: float, repair: float = 0.5
) -> dict[str, object]:
    return {
        "clean": {"false_alarm_rate": fa, "repair_rms_m": repair},
        "grad": {
            "anomaly": {"f1": f1},
            "normal": {"recall": nr},
            "recovery_rmse_m": rec,
            "corrupted_rmse_m": cor,
        },
    }


def test_verdicts_follow_issue_13_targets() -> None:
    good = _cell(0.005, 0.95, 0.99, 10.0, 50.0)
    assert judge("native", good) == []
    assert judge("1 Hz", good) == []
    assert judge("native", _cell(0.0051, 0.99, 1.0, 1, 2)) == ["false alarms 0.51 % > 0.50 %"]
    assert judge("1 Hz", _cell(0, 0.949, 0.989, 1, 2)) == [
        "anomaly F1 0.949 < 0.95",
        "normal recall 0.989 < 0.99",
    ]
    # 0.5 Hz: looser false alarms and F1, no normal-recall target.
    assert judge("0.5 Hz", _cell(0.01, 0.90, 0.5, 1, 2)) == []
    assert judge("0.5 Hz", _cell(0.011, 0.9, 0.5, 1, 2))[0].startswith("false alarms")
    # Recovery must beat the corrupted fixes in every cell; missing numbers fail.
    assert judge("native", _cell(0, 1, 1, 50.0, 50.0))[0].startswith("recovery RMSE")
    # The untouched drive's repair stays within 1 m RMS of its fixes.
    assert judge("0.5 Hz", _cell(0, 1, 1, 1, 2, repair=1.0)) == []
    assert judge("0.5 Hz", _cell(0, 1, 1, 1, 2, repair=1.01)) == ["clean repair RMS 1.010 m > 1 m"]
    assert len(judge("native", _cell(math.nan, math.nan, math.nan, math.nan, 1, math.nan))) == 5


def test_unknown_names_are_config_errors() -> None:
    result = CliRunner().invoke(main, ["bench", "--suite", "robustness", "--detector", "nope"])
    assert result.exit_code == 1
    assert "unknown detector 'nope'" in result.output
    with pytest.raises(ConfigError, match="'simulated' is not in the robustness suite"):
        run_robustness(Detector(), "grad-default", datasets=["simulated"])


def test_suite_shape_on_tiny_data(tmp_path: Path) -> None:
    """The whole suite through the CLI on tiny stand-ins: every cell there, numbers not checked."""
    _tiny_data(tmp_path)
    write_tiny_new_drives(tmp_path)
    out = tmp_path / "robustness.json"
    result = CliRunner().invoke(
        main, ["bench", "--suite", "robustness", "--data-dir", str(tmp_path), "--json", str(out)]
    )
    assert result.exit_code == 0, result.output
    report = json.loads(out.read_text())
    assert report["detector"] == "grad-default"
    assert report["seed"] == 0
    assert report["datasets"] == list(ROBUSTNESS_DATASETS)
    variants = {
        "driveplotr": 3,
        "tuc": 3,
        "nl_motorway": 1,
        "nl_motorway_gopro": 2,
        "austin2006": 1,
        "nevada": 3,
        "ublox_f9k": 3,
        "munich": 1,
    }
    cells = report["cells"]
    assert len(cells) == report["n_cells"] == 3 * sum(variants.values())
    for name, n in variants.items():
        mine = [c for c in cells if c["dataset"] == name]
        assert len(mine) == 3 * n, name
        assert [c["rate"] for c in mine] == list(RATES) * n
    same = {(c["dataset"], c["rate"]) for c in cells if c["same_as"]}
    # 1 Hz data is its own 1 Hz cell; 0.5 Hz data its own 1 Hz and 0.5 Hz; 2 Hz data none.
    assert ("nl_motorway", "1 Hz") in same
    assert ("nl_motorway", "0.5 Hz") not in same
    assert {("nevada", "1 Hz"), ("nevada", "0.5 Hz")} <= same
    assert not any(d == "ublox_f9k" for d, _ in same)
    for c in cells:
        assert isinstance(c["passed"], bool)
        assert isinstance(c["misses"], list)
        if c["same_as"]:
            continue
        assert set(c["grad"]["anomaly"]) == {"precision", "recall", "f1"}
        for key in ("event_recall", "detection_delay_median_s", "recovery_rmse_m"):
            assert key in c["grad"]
        assert {"false_alarm_rate", "repair_rms_m", "glitch_recall"} <= set(c["clean"])
        has_glitch = c["dataset"] in ("austin2006", "munich")
        assert (c["clean"]["glitch_rows"] > 0) == has_glitch
    assert report["passed"] == sum(c["passed"] for c in cells)
    text = result.stdout
    assert "| data set | columns | native | 1 Hz | 0.5 Hz |" in text
    assert "gradgps bench --suite robustness --detector grad-default" in text
    assert "load average" in text
    assert text.count("| nevada | +speed+heading | ") == 2  # matrix row + one scored cell
    assert robustness_markdown(report, "x")[0].startswith("### Robustness suite")


def test_protocol_mode_still_needs_its_options() -> None:
    result = CliRunner().invoke(main, ["bench", "--dataset", "tuc", "--detector", "rema"])
    assert result.exit_code == 2
    assert "--protocol" in result.output


@pytest.mark.shared
def test_real_glitches_are_scored_apart(shared_data: Path) -> None:
    report = run_robustness(Detector(), "grad-default", datasets=["munich"], data_dir=shared_data)
    native = report["cells"][0]
    assert (native["variant"], native["rate"]) == ("positions", "native")
    assert native["rows"] == 1194
    assert native["clean"]["glitch_rows"] == 35
    assert native["clean"]["rows_scored"] == 1194 - 35
    assert native["grad"]["faulty_rows"] > 0


def _drive_north(speeds: list[float], track: str = "a") -> pd.DataFrame:
    """1 Hz fixes moving north at ``speeds`` (m/s per step; 0 repeats the fix exactly)."""
    metres = np.r_[0.0, np.cumsum(speeds)]
    lat = 52.0 + metres / 111_195.0
    lat[1:][np.asarray(speeds) == 0.0] = np.nan
    lat = pd.Series(lat).ffill().to_numpy()  # a repeat is the very same value
    return pd.DataFrame(
        {"track": track, "t": np.arange(len(lat), dtype=float), "lat": lat, "lon": 4.4}
    )


def test_evident_holds_are_repeats_at_speed_left_by_a_catch_up() -> None:
    # 10 m/s, the fix held twice, then a 30 m catch-up: the two repeats are held.
    held = _drive_north([10, 10, 10, 0, 0, 30, 10, 10])
    assert evident_holds(held).tolist() == [False] * 4 + [True, True] + [False] * 3
    # A car that brakes from 10 m/s, stands, and starts slowly: a stop, not a hold.
    stop = _drive_north([10, 10, 6, 0, 0, 0, 2, 5, 8])
    assert not evident_holds(stop).any()
    # Repeats while creeping (4 m/s < 5 m/s) are not evident.
    assert not evident_holds(_drive_north([4, 4, 0, 9, 4])).any()
    # A repeat at the start of a track, or left by no step at all, is not judged.
    assert not evident_holds(_drive_north([0, 0, 10, 10])).any()
    assert not evident_holds(_drive_north([10, 10, 0, 0])).any()


def test_evident_holds_follow_each_track_in_time_order() -> None:
    a = _drive_north([10, 10, 0, 25, 10], "a")
    b = _drive_north([10, 10, 10, 10, 10], "b")
    # b starts exactly where a ended: a repeat across tracks is no hold.
    b["lat"] = b["lat"] - b["lat"].iloc[0] + a["lat"].iloc[-1]
    assert b["lat"].iloc[0] == a["lat"].iloc[-1]
    table = pd.concat([a, b]).iloc[::-1].reset_index(drop=True)  # rows in reverse
    expected = (table["track"] == "a") & (table["t"] == 3.0)
    assert evident_holds(table).tolist() == expected.tolist()


def test_more_fault_draws_add_their_spread_and_keep_seed_0s_verdicts(tmp_path: Path) -> None:
    """``draws`` scores seeds 1..N-1 beside seed 0 in every scored cell: seed 0's numbers
    and every verdict are those of a one-draw run, the other draws are really other
    faults, and the Markdown adds one spread row per scored cell."""
    _tiny_data(tmp_path)
    write_tiny_new_drives(tmp_path)
    det = Detector()
    one = run_robustness(det, "grad-default", datasets=["driveplotr"], data_dir=tmp_path)
    three = run_robustness(det, "grad-default", datasets=["driveplotr"], data_dir=tmp_path, draws=3)
    assert one["draws"] == 1
    assert three["draws"] == 3
    assert [c["passed"] for c in three["cells"]] == [c["passed"] for c in one["cells"]]
    scored = [c for c in three["cells"] if not c["same_as"]]
    assert scored
    for c, c1 in zip(three["cells"], one["cells"], strict=True):
        if c["same_as"]:
            continue
        assert "draws" not in c1["grad"]
        d = c["grad"]["draws"]
        assert d["seeds"] == [0, 1, 2]
        assert d["anomaly_f1"][0] == c1["grad"]["anomaly"]["f1"]
        assert d["normal_recall"][0] == c1["grad"]["normal"]["recall"]
    # other seeds inject other faults: not every cell scores the same in all three draws
    assert any(len(set(c["grad"]["draws"]["anomaly_f1"])) > 1 for c in scored)
    text = robustness_markdown(three, "x")
    assert "Spread over 3 fault draws" in "\n".join(text)
    rows = [line for line in text if line.startswith("| driveplotr |") and " of 3 |" in line]
    assert len(rows) == len(scored)
    assert not any("Spread over" in line for line in robustness_markdown(one, "x"))
    bad = CliRunner().invoke(main, ["bench", "--suite", "robustness", "--draws", "0"])
    assert bad.exit_code == 2
    with pytest.raises(ConfigError, match="draws must be at least 1"):
        run_robustness(det, "grad-default", datasets=["driveplotr"], data_dir=tmp_path, draws=0)

"""The peers (``_baselines/peers.py``) and their table (``benchmarks/peers.py --quick``, shape only)."""

from __future__ import annotations

import json
import math
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from gradgps._baselines.peers import PEER_NAMES, STREAMING_PEERS, PeerDetector, peer_stream
from gradgps._exceptions import ConfigError
from gradgps._tracks.geo import LocalFrame

REPO = Path(__file__).resolve().parents[1]


def _drive(n: int = 300, jump_at: int = 150, jump_m: float = 200.0) -> pd.DataFrame:
    """A 1 Hz drive on a gentle curve at 15 m/s with one 200 m jump (one fix)."""
    rng = np.random.default_rng(3)
    t = np.arange(n, dtype=float)
    heading = 30.0 + 0.05 * t
    east = np.cumsum(15.0 * np.sin(np.radians(heading))) + rng.normal(0, 1.0, n)
    north = np.cumsum(15.0 * np.cos(np.radians(heading))) + rng.normal(0, 1.0, n)
    east[jump_at] += jump_m
    lat, lon = LocalFrame(50.0, 8.0).to_geodetic(east, north)
    return pd.DataFrame(
        {
            "track": "a",
            "t": t,
            "lat": lat,
            "lon": lon,
            "speed": np.full(n, 15.0),
            "heading": heading % 360.0,
        }
    )


@pytest.mark.parametrize("name", ["kalman-chi2", "kalman-chi2-vel", "hampel", "river-gauss"])
def test_peer_flags_an_obvious_jump_and_keeps_every_row(name: str) -> None:
    fixes = _drive()
    fixes.loc[7, "lat"] = math.nan  # an unusable row: kept, flagged with its reason
    out = PeerDetector(name).detect(fixes)
    assert list(out.index) == list(fixes.index)
    assert out.loc[150, "anomaly"] == 1
    assert out.loc[7, "anomaly"] == 1  # the one invalid-row policy (gradgps._result)
    assert out.loc[7, "invalid_reason"] != ""
    assert out["anomaly"].sum() < 30


@pytest.mark.parametrize("name", ["kalman-chi2", "kalman-chi2-vel", "river-hst"])
def test_streaming_and_batch_agree(name: str) -> None:
    fixes = _drive(120, 60)
    batch = PeerDetector(name).detect(fixes)
    detector = PeerDetector(name)
    stream = peer_stream(name, detector.settings_for("+speed+heading"), "+speed+heading")
    flags = [
        stream.update(r.t, r.lat, r.lon, r.speed, r.heading).anomaly
        for r in fixes.itertuples(index=False)
    ]
    assert flags == batch["anomaly"].tolist()


@pytest.mark.parametrize("name", STREAMING_PEERS)
def test_peer_stream_checks_each_fix_as_the_baselines_do(name: str) -> None:
    """An unusable fix (None, NaN, text, out of range, before the previous one) is flagged
    with its reason, raises nothing and leaves the stream as it was; a missing row
    streamed gets the batch's verdict (the one invalid-row policy, gradgps._result)."""
    fixes = _drive(40, 20)
    settings = PeerDetector(name).settings_for("+speed+heading")
    bad_fed = peer_stream(name, settings, "+speed+heading")
    clean_fed = peer_stream(name, settings, "+speed+heading")
    rows = list(fixes.itertuples(index=False))
    for r in rows[:10]:
        bad_fed.update(r.t, r.lat, r.lon, r.speed, r.heading)
        clean_fed.update(r.t, r.lat, r.lon, r.speed, r.heading)
    last = rows[9]
    for args in (
        (None, last.lat, last.lon),
        (last.t + 1, None, last.lon),
        (math.nan, last.lat, last.lon),
        ("not a time", last.lat, last.lon),
        (last.t + 1, 95.0, last.lon),
        (last.t - 3.0, last.lat, last.lon),
    ):
        out = bad_fed.update(*args)
        assert out.anomaly == 1, (args, out)
        assert out.invalid_reason, (args, out)
        assert math.isnan(out.score), (args, out)
        assert math.isnan(out.lat_clean), (args, out)
    for r in rows[10:]:
        a = bad_fed.update(r.t, r.lat, r.lon, r.speed, r.heading)
        b = clean_fed.update(r.t, r.lat, r.lon, r.speed, r.heading)
        assert a == b

    holes = fixes.copy()
    holes.loc[[5, 25], "lat"] = math.nan
    batch = PeerDetector(name).detect(holes)
    stream = peer_stream(name, settings, "+speed+heading")
    verdicts = [
        stream.update(r.t, r.lat, r.lon, r.speed, r.heading) for r in holes.itertuples(index=False)
    ]
    assert [v.anomaly for v in verdicts] == batch["anomaly"].tolist()
    assert [v.invalid_reason for v in verdicts] == batch["invalid_reason"].tolist()


def test_missing_extra_is_one_line_naming_it(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setitem(sys.modules, "river.anomaly", None)  # import fails as if not installed
    with pytest.raises(ConfigError, match="extra 'peers'") as info:
        PeerDetector("river-hst").detect(_drive(20, 10))
    assert "\n" not in str(info.value)


def test_unknown_peer_names_the_known_ones() -> None:
    with pytest.raises(ConfigError, match="known peers: movingpandas-outlier"):
        PeerDetector("nope").detect(_drive(20, 10))


def _tiny_data(folder: Path) -> None:
    from gradgps import simulate_fleet

    fleet = simulate_fleet(6, 1.0, 1.0, seed=5)
    ids = dict(zip(sorted(fleet["track"].unique()), [1, 2, 9, 10, 11, 14], strict=True))
    pd.DataFrame(
        {
            "drive": fleet["track"].map(ids),
            "t": fleet["t"].round().astype("int64"),
            "lat": fleet["lat"],
            "lon": fleet["lon"],
            "speed_mps": fleet["speed"],
            "heading_deg": fleet["heading"],
        }
    ).to_csv(folder / "driveplotr_nds.csv", index=False)
    names = ["a", "b", "frankfurt_westend_tower", "c", "chemnitz_city", "d"]
    pd.DataFrame(
        {
            "trace": fleet["track"].map(
                dict(zip(sorted(fleet["track"].unique()), names, strict=True))
            ),
            "t_rel": fleet["t"] - fleet["t"].min(),
            "lat": fleet["lat"],
            "lon": fleet["lon"],
        }
    ).to_csv(folder / "tuc_urban_gt.csv", index=False)


def test_quick_peers_table_shape(tmp_path: Path) -> None:
    data = tmp_path / "data"
    data.mkdir()
    _tiny_data(data)
    markdown = tmp_path / "BENCHMARKS.md"
    markdown.write_text("# Benchmarks\n\n<!-- bench:start -->\nkept\n<!-- bench:end -->\n")
    env = {**os.environ, "PYTHONPATH": str(REPO / "src")}
    cmd = [sys.executable, str(REPO / "benchmarks" / "peers.py"), "--quick"]
    cmd += ["--dataset", "driveplotr", "--dataset", "tuc", "--data-dir", str(data)]
    cmd += ["--results", str(tmp_path), "--markdown", str(markdown)]
    cmd += ["--tuned", str(tmp_path / "tuned.json")]
    subprocess.run(cmd, check=True, env=env, capture_output=True, timeout=300)
    report = json.loads((tmp_path / "bench_peers_quick.json").read_text())
    tuned = json.loads((tmp_path / "tuned.json").read_text())
    assert set(tuned) == {"driveplotr", "tuc"}
    tables = report["tables"]
    # the TUC-shaped file has no speed/heading: only the positions variant
    assert set(tables["driveplotr"]["variants"]) == {"positions", "+speed+heading"}
    assert set(tables["tuc"]["variants"]) == {"positions"}
    peers = set(PEER_NAMES) - {"skmob-filter"}  # its environment is not built in quick mode
    rows = tables["driveplotr"]["variants"]["+speed+heading"]
    assert set(rows) == peers | {"grad-default"}
    assert set(tables["tuc"]["variants"]["positions"]) == peers - {"kalman-chi2-vel"} | {
        "grad-default"
    }
    for row in rows.values():
        assert set(row["split"]) == {"precision", "recall", "f1"}
        assert set(row["whole_file"]) == {"precision", "recall", "f1"}
        assert 0.0 <= row["clean_false_alarm_pct"] <= 100.0
        assert row["batch_us"] > 0
    assert rows["kalman-chi2"]["stream_us"] > 0
    assert rows["hampel"]["stream_us"] is None
    assert rows["grad-default"]["f1_ratio_to_grad"] in (1.0, None)
    text = markdown.read_text()
    assert "<!-- bench:start -->\nkept\n<!-- bench:end -->" in text  # other sections stay
    assert text.count("<!-- peers:start -->") == 1
    assert "quick mode" in text
    assert text.count("### driveplotr, test split") == 2


def test_bench_cli_runs_a_peer_and_needs_protocol_without_suite(tmp_path: Path) -> None:
    from click.testing import CliRunner

    from gradgps._cli import main

    _tiny_data(tmp_path)
    runner = CliRunner()
    res = runner.invoke(main, ["bench", "--dataset", "tuc", "--data-dir", str(tmp_path)])
    assert res.exit_code != 0
    assert "missing option '--protocol' (needed without --suite)" in res.output
    args = ["bench", "--protocol", "grad", "--dataset", "tuc", "--detector", "hampel,kalman-chi2"]
    res = runner.invoke(main, [*args, "--data-dir", str(tmp_path)])
    assert res.exit_code == 0, res.output
    assert "hampel" in res.output
    assert "kalman-chi2" in res.output


def test_skmob_filter_in_its_own_environment() -> None:
    from gradgps._baselines import skmob_peer

    venv = Path(os.environ.get("GRADGPS_SKMOB_VENV") or Path.cwd() / ".venv-skmob")
    if not (venv / ".stamp-skmob").is_file():
        pytest.skip(
            f"no scikit-mobility environment at {venv}: building it compiles python-igraph "
            "(minutes); python benchmarks/peers.py creates it on first use"
        )
    out = PeerDetector("skmob-filter", {"+speed+heading": {"max_speed_kmh": 150.0}}).detect(
        _drive()
    )
    assert out.loc[150, "anomaly"] == 1
    assert out["anomaly"].sum() < 5
    assert skmob_peer.SKMOB_REQUIREMENTS[0] == "scikit-mobility==1.3.1"

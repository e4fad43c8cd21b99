"""Honest inputs: warnings where a file is outside what the model was validated on."""

from __future__ import annotations

import itertools
import json
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd
import pytest
from click.testing import CliRunner

from gradgps._tracks.geo import LocalFrame
from gradgps._tracks.input_checks import InputChecks, input_warnings, validated_rates
from gradgps._tracks.summary import summarize


def _track(t: np.ndarray, speed: float = 20.0, name: str = "a") -> pd.DataFrame:
    """Canonical fixes of a straight drive north at ``speed`` m/s, sampled at times ``t``."""
    frame = LocalFrame(52.0, 4.4)
    north = speed * (t - t[0])
    lat, lon = frame.to_geodetic(np.zeros_like(north), north)
    return pd.DataFrame({"track": name, "t": t, "lat": lat, "lon": lon})


def _kinds(fixes: pd.DataFrame, **rates: float) -> set[str]:
    kinds = set()
    for w in input_warnings(fixes, **rates):
        for key, kind in (
            ("slower than", "slow"),
            ("faster than", "fast"),
            ("repeat the previous", "repeats"),
            ("imply speeds", "speeds"),
            ("irregular", "irregular"),
            ("noisy fixes", "noisy"),
        ):
            if key in w:
                kinds.add(kind)
    return kinds


def _through_states(fixes: pd.DataFrame, size: int) -> InputChecks:
    """The checks of ``fixes`` fed ``size`` rows at a time, each time from the state the
    last chunk left, written to JSON and read back (a stream worker's life)."""
    chunked = InputChecks()
    for lo in range(0, len(fixes), size):
        chunked = InputChecks.from_state(json.loads(json.dumps(chunked.to_state())))
        chunked.add(fixes.iloc[lo : lo + size])
    return chunked


REGULAR = np.arange(300.0)


def test_an_ordinary_drive_gets_no_warning() -> None:
    assert input_warnings(_track(REGULAR)) == []
    jitter = REGULAR + np.random.default_rng(0).uniform(-0.1, 0.1, REGULAR.size)
    assert input_warnings(_track(np.sort(jitter))) == []


def test_slow_sampling_is_named_with_the_validated_rate() -> None:
    assert _kinds(_track(np.arange(300.0) * 5.0)) == {"slow"}
    assert _kinds(_track(np.arange(300.0) * 2.0)) == set()  # 0.5 Hz is validated
    (warning,) = input_warnings(_track(np.arange(300.0) * 5.0))
    assert "5 s (0.2 Hz)" in warning
    assert "0.5 Hz" in warning
    # A model validated down to 1 Hz only: 0.5 Hz is outside.
    assert _kinds(_track(np.arange(300.0) * 2.0), min_rate_hz=1.0) == {"slow"}


def test_fast_sampling_beyond_the_validated_rate() -> None:
    assert _kinds(_track(np.arange(300.0) * 0.05)) == {"fast"}  # 20 Hz
    assert _kinds(_track(np.arange(300.0) * 0.1)) == set()  # 10 Hz


def test_repeated_timestamps() -> None:
    t = REGULAR.copy()
    t[100:110] = t[99]  # 10 of 299 steps repeat a timestamp (3 %)
    assert _kinds(_track(np.sort(t))) >= {"repeats"}
    t = REGULAR.copy()
    t[100] = t[99]  # one (0.3 %): not worth a warning
    assert "repeats" not in _kinds(_track(t))


def test_implausible_speeds() -> None:
    assert _kinds(_track(REGULAR, speed=500.0)) == {"speeds"}  # e.g. a wrong time unit
    # A few real glitches (jumps away and back) are what the detector is for.
    fixes = _track(REGULAR)
    fixes.loc[[50, 120], "lat"] += 0.01  # ~1.1 km away for one fix each: 4 fast steps
    assert _kinds(fixes) == set()
    (warning,) = input_warnings(_track(REGULAR, speed=500.0))
    assert "299 of 299 time steps" in warning
    assert "500 m/s" in warning


def test_irregular_sampling() -> None:
    steps = np.tile([1.0, 1.0, 3.0], 100)  # quartiles 1 s and 3 s around a median of 1 s
    assert _kinds(_track(np.cumsum(steps))) == {"irregular"}


def test_chunks_give_the_same_warnings_as_the_whole_file() -> None:
    rng = np.random.default_rng(3)
    t = np.cumsum(rng.choice([1.0, 1.0, 4.0, 0.0], size=900))
    fixes = pd.concat([_track(t, 120.0, "a"), _track(t, 20.0, "b")]).reset_index(drop=True)
    whole = InputChecks().add(fixes)
    chunked = InputChecks()
    for lo in range(0, len(fixes), 250):
        chunked.add(fixes.iloc[lo : lo + 250])
    assert whole.warnings() == chunked.warnings()
    assert len(whole.warnings()) >= 2
    assert (whole.hist == chunked.hist).all()
    assert (whole.second_diff_hist == chunked.second_diff_hist).all()
    assert whole.repeats == chunked.repeats


def test_invalid_fixes_and_single_fixes_give_no_warning() -> None:
    fixes = _track(REGULAR[:1])
    assert input_warnings(fixes) == []
    bad = _track(REGULAR)
    bad.loc[::2, "lat"] = np.nan
    assert input_warnings(bad) == []


def test_validated_rates_come_from_the_model_config() -> None:
    assert validated_rates(None) == (0.5, 10.0)
    assert validated_rates({"validated": {"min_rate_hz": 1, "max_rate_hz": 20}}) == (1.0, 20.0)
    assert validated_rates({"other": 1}) == (0.5, 10.0)


def test_summary_lists_the_warnings() -> None:
    summary = summarize(_track(np.arange(300.0) * 5.0))
    assert len(summary.warnings) == 1
    assert "slower than" in summary.warnings[0]
    assert summary.as_dict()["warnings"] == summary.warnings
    assert summarize(_track(REGULAR)).warnings == []


@pytest.mark.parametrize("chunk_size", ["0", "100"])
def test_detect_says_it_once_on_stderr(tmp_path: Path, chunk_size: str) -> None:
    from gradgps._cli import main

    slow = _track(np.arange(200.0) * 5.0)
    src = tmp_path / "slow.csv"
    slow.to_csv(src, index=False)
    runner = CliRunner()
    result = runner.invoke(
        main, ["detect", str(src), "-o", str(tmp_path / "out.csv"), "--chunk-size", chunk_size]
    )
    assert result.exit_code == 0, result.output
    lines = [line for line in result.stderr.splitlines() if line.startswith("warning: ")]
    assert len(lines) == 1
    assert "slower than the slowest rate" in lines[0]
    assert "warning" not in result.stdout
    ok = tmp_path / "ok.csv"
    _track(REGULAR).to_csv(ok, index=False)
    result = runner.invoke(
        main, ["detect", str(ok), "-o", str(tmp_path / "o2.csv"), "--chunk-size", chunk_size]
    )
    assert result.exit_code == 0
    assert "warning" not in result.output


def test_report_summary_lists_the_warnings(tmp_path: Path) -> None:
    pytest.importorskip("matplotlib")
    from gradgps._cli import main

    src = tmp_path / "slow.csv"
    _track(np.arange(200.0) * 5.0).to_csv(src, index=False)
    report = tmp_path / "r.html"
    result = CliRunner().invoke(
        main, ["detect", str(src), "-o", str(tmp_path / "o.csv"), "--report", str(report)]
    )
    assert result.exit_code == 0, result.output
    html = report.read_text()
    assert html.count("slower than the slowest rate the model was validated on") == 1


def _noisy(sigma_m: float, seed: int = 0, t: np.ndarray = REGULAR) -> pd.DataFrame:
    """A straight drive whose fixes scatter by ``sigma_m`` m per axis, independently."""
    fixes = _track(t)
    rng = np.random.default_rng(seed)
    fixes["lat"] += rng.normal(0.0, sigma_m, len(fixes)) / 111_195.0
    fixes["lon"] += rng.normal(0.0, sigma_m, len(fixes)) / (111_195.0 * np.cos(np.radians(52.0)))
    return fixes


def test_a_noisy_receiver_is_named_with_its_noise() -> None:
    """Fixes scattering by 3 m per axis land about 7 m off their predecessors' line (the
    second difference of independent errors: sqrt(6) sigma, a median of 1.18 of that);
    by 0.3 m: under a metre, like every real drive the model knows."""
    assert "noisy" in _kinds(_noisy(3.0))
    (warning,) = input_warnings(_noisy(3.0))
    assert "m off the line" in warning
    assert "1.3 m" in warning
    assert _kinds(_noisy(0.3)) == set()
    checks = InputChecks().add(_noisy(3.0))
    assert 5.0 < checks.second_difference_median() < 12.0
    # Too few triples say nothing; uneven steps make no triple.
    assert _kinds(_noisy(3.0).iloc[:40]) == set()
    assert (
        InputChecks().add(_track(np.cumsum(np.tile([1.0, 2.0], 100)))).second_diff_hist.sum() == 0
    )


# A reported speed or heading held against the positions (the witness checks).


def _winding(
    period_s: float = 1.0, minutes: float = 10.0, noise_m: float = 0.0, seed: int = 0
) -> pd.DataFrame:
    """Canonical fixes of a winding drive (10-30 m/s, the heading swinging through every
    direction) with its true speed (m/s) and heading (degrees clockwise from north)."""
    rng = np.random.default_rng(seed)
    fine = 0.01
    tt = np.arange(0.0, minutes * 60.0 + fine, fine)
    speed = 20.0 + 10.0 * np.sin(tt / 37.0)
    heading = (200.0 * np.sin(tt / 53.0) + 0.5 * tt) % 360.0
    rad = np.radians(heading)
    east = np.cumsum(speed * np.sin(rad)) * fine
    north = np.cumsum(speed * np.cos(rad)) * fine
    pick = np.arange(0, tt.size, round(period_s / fine))
    e = east[pick] + rng.normal(0.0, noise_m, pick.size)
    n = north[pick] + rng.normal(0.0, noise_m, pick.size)
    lat, lon = LocalFrame(52.0, 4.4).to_geodetic(e, n)
    return pd.DataFrame(
        {
            "track": "a",
            "t": tt[pick],
            "lat": lat,
            "lon": lon,
            "speed": speed[pick],
            "heading": heading[pick],
        }
    )


def _witness_kinds(fixes: pd.DataFrame) -> set[str]:
    out = set()
    for w in input_warnings(fixes):
        if w.startswith("reported speed"):
            out.add("speed")
        if w.startswith("reported heading"):
            out.add("heading")
    return out


@pytest.mark.parametrize("period_s", [0.1, 0.2, 1.0, 2.0])
def test_a_speed_and_heading_that_agree_with_the_positions_get_no_warning(
    period_s: float,
) -> None:
    fixes = _winding(period_s, noise_m=1.0)
    assert _witness_kinds(fixes) == set()
    share, typical, n = InputChecks().add(fixes).speed_agreement()
    assert n >= 100
    assert share > 0.9
    assert typical == pytest.approx(1.0, rel=0.03)
    heading_share, _ = InputChecks().add(fixes).heading_agreement()
    assert heading_share > 0.9


@pytest.mark.parametrize(("unit", "factor"), [("km/h", 3.6), ("mph", 2.23694), ("knots", 1.94384)])
def test_a_speed_in_another_unit_is_named_with_the_flag_that_reads_it(
    unit: str, factor: float
) -> None:
    fixes = _winding()
    fixes["speed"] *= factor  # what reading km/h values as m/s gives
    assert _witness_kinds(fixes) == {"speed"}
    (warning,) = input_warnings(fixes)
    assert f"pass --speed-unit {unit}" in warning
    typical = float(warning.split("typically ")[1].split(" times")[0])
    assert typical == pytest.approx(factor, rel=0.02)
    assert "read in m/s" in warning


def test_a_declared_unit_that_is_wrong_is_named_too() -> None:
    """A column called speed_kmh that holds m/s: read in km/h, it is 0.28 times the chord."""
    fixes = _winding()
    fixes["speed"] /= 3.6
    fixes.attrs["speed_unit"] = "km/h"
    (warning,) = input_warnings(fixes)
    assert "read in km/h" in warning
    assert "pass --speed-unit m/s" in warning
    # The same values read in m/s match no unit mix-up: the message says what to check.
    del fixes.attrs["speed_unit"]
    (warning,) = input_warnings(fixes)
    assert "check the column and its unit" in warning


@pytest.mark.parametrize(
    ("convert", "reading"),
    [
        (lambda h: np.radians(h), "radians"),
        (lambda h: np.radians((h + 180.0) % 360.0 - 180.0), "radians"),  # -pi..pi
        (lambda h: (90.0 - h) % 360.0, "counter-clockwise from east"),
    ],
)
def test_a_heading_in_another_convention_is_named(convert: object, reading: str) -> None:
    fixes = _winding()
    fixes["heading"] = np.mod(convert(fixes["heading"].to_numpy()), 360.0)  # type: ignore[operator]
    assert _witness_kinds(fixes) == {"heading"}
    (warning,) = input_warnings(fixes)
    assert f"read as {reading} it agrees" in warning
    assert "--heading-col ''" in warning


def test_a_heading_that_fits_no_convention_says_check_the_column() -> None:
    fixes = _winding()
    fixes["heading"] = np.random.default_rng(1).uniform(0.0, 360.0, len(fixes))
    (warning,) = input_warnings(fixes)
    assert "check the column" in warning


def test_faults_in_the_positions_do_not_make_the_witness_look_wrong() -> None:
    """Protocol ``grad`` (10-50 m noise, 20-200 m jumps): the faults' steps disagree, the
    clean ones still agree."""
    from gradgps import inject_grad

    clean = _winding(1.0, minutes=30.0, noise_m=1.0)
    faulty = inject_grad(clean, seed=0)
    assert faulty["label_anomaly"].sum() > 0.05 * len(faulty)
    checks = InputChecks().add(faulty[list(clean.columns)])
    assert checks.speed_agreement()[0] > 0.6
    assert checks.heading_agreement()[0] > 0.6
    assert _witness_kinds(faulty[list(clean.columns)]) == set()


def test_a_standing_or_slow_drive_says_nothing_about_its_witness() -> None:
    """Below 5 m/s, or over fewer than MIN_WITNESS_STEPS steps, a chord's direction and
    length are mostly the receiver's noise: no comparison, no warning."""
    fixes = _winding(noise_m=1.0)
    fixes["heading"] = (fixes["heading"] + 90.0) % 360.0
    assert _witness_kinds(fixes.iloc[:40]) == set()
    standing = _track(REGULAR, speed=2.0)
    standing["speed"] = 20.0
    standing["heading"] = 90.0
    assert _witness_kinds(standing) == set()
    assert InputChecks().add(standing).speed_agreement()[2] == 0


def test_witness_checks_in_chunks_equal_the_whole_file() -> None:
    fixes = pd.concat(
        [_winding(1.0, noise_m=1.0).assign(track="a"), _winding(0.1, minutes=3.0).assign(track="b")]
    ).reset_index(drop=True)
    fixes.loc[fixes["track"] == "b", "speed"] *= 3.6
    fixes.loc[::7, "speed"] = np.nan  # a fix without a speed takes its neighbour's
    whole = InputChecks().add(fixes)
    for size in (1, 97, 1000):
        chunked = InputChecks()
        for lo in range(0, len(fixes), size):
            chunked.add(fixes.iloc[lo : lo + size])
        assert (whole.speed_ratio_hist == chunked.speed_ratio_hist).all()
        assert (whole.heading_diff_hist == chunked.heading_diff_hist).all()
        assert whole.warnings() == chunked.warnings()


@pytest.mark.shared
def test_every_real_drive_s_speed_and_heading_agree_with_its_positions(shared_data: Path) -> None:
    """On every split of every real data set with a speed or heading, clean and with
    protocol ``grad`` or ``gnss`` faults injected (seed 0): no witness warning, and at
    least 90 % (clean) or 60 % (faults) of the moving steps agree."""
    from gradgps._data.datasets import load_dataset
    from gradgps._tracks.track import to_fixes
    from gradgps.inject import inject_gnss, inject_grad

    checked = 0
    for name in ("driveplotr", "tuc", "nl_motorway_gopro", "nevada", "ublox_f9k"):
        for split in ("train", "validation", "test"):
            if name == "ublox_f9k" and split != "test":
                continue
            table = load_dataset(name, split, data_dir=shared_data)
            fixes = to_fixes(table)
            cmap = fixes.attrs["columns"]
            for faults, least in ((None, 0.9), (inject_grad, 0.6), (inject_gnss, 0.6)):
                data = fixes
                if faults is not None:
                    data = to_fixes(faults(table, seed=0, columns=cmap)[list(table.columns)], cmap)
                checks = InputChecks().add(data)
                where = f"{name} {split} {faults.__name__ if faults else 'clean'}"
                assert not [w for w in checks.warnings() if w.startswith("reported")], where
                share, typical, n = checks.speed_agreement()
                assert n > 100, where
                assert share >= least, (where, share)
                assert typical == pytest.approx(1.0, rel=0.03), where
                if "heading" in data:
                    share, n = checks.heading_agreement()
                    assert n > 100, where
                    assert share >= least, (where, share)
                checked += 1
    assert checked == 39


def test_detect_names_a_speed_in_km_h_once_and_reads_it_with_the_flag(tmp_path: Path) -> None:
    from gradgps._cli import main

    fixes = _winding()
    fixes["speed"] *= 3.6
    src = tmp_path / "kmh.csv"
    fixes.drop(columns=["track"]).to_csv(src, index=False)
    runner = CliRunner()
    result = runner.invoke(main, ["detect", str(src), "-o", str(tmp_path / "o.csv")])
    assert result.exit_code == 0, result.output
    lines = [line for line in result.stderr.splitlines() if line.startswith("warning: ")]
    assert len(lines) == 1
    assert "reported speed (column 'speed', read in m/s)" in lines[0]
    assert "--speed-unit km/h" in lines[0]
    result = runner.invoke(
        main, ["detect", str(src), "-o", str(tmp_path / "o.csv"), "--speed-unit", "km/h"]
    )
    assert result.exit_code == 0, result.output
    assert "warning" not in result.stderr


def test_the_python_api_warns_once_per_problem_and_call(tmp_path: Path) -> None:
    """Detector.detect / clean and gradgps.detect / clean say what the command line says,
    as gradgps.InputWarning; an ordinary drive gets none."""
    import warnings

    import gradgps

    fixes = _winding()
    kmh = fixes.assign(speed=fixes["speed"] * 3.6)
    det = gradgps.Detector()
    for call in (det.detect, det.clean, gradgps.detect, gradgps.clean):
        with pytest.warns(gradgps.InputWarning, match="pass --speed-unit km/h") as seen:
            call(kmh)
        assert len(seen) == 1
        with warnings.catch_warnings():
            warnings.simplefilter("error")
            call(fixes)
    # Named by the caller's keyword, the unit reads right and nothing is said.
    table = kmh.rename(columns={"speed": "speed_kmh"})
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        gradgps.detect(table, speed="speed_kmh")


def test_faults_do_not_make_a_clean_receiver_noisy() -> None:
    """Protocol ``grad`` moves the three triples around each faulty fix by tens of metres:
    the median of a clean 0.5 Hz drive's second differences goes above 3 m, its lower
    quartile stays near the receiver's own; a noisy receiver with faults is still named."""
    from gradgps import inject_grad

    clean = _noisy(0.9, t=np.arange(1800.0) * 2.0)  # a logger's metre of noise at 0.5 Hz
    assert "noisy" not in _kinds(clean)
    faulty = inject_grad(clean, seed=0)[list(clean.columns)]
    checks = InputChecks().add(faulty)
    assert checks.second_difference_median() > 3.0  # what the median made of it
    assert checks.second_difference_quartile()[0] < 2.2
    assert "noisy" not in _kinds(faulty)
    noisy = _noisy(3.0, t=np.arange(1200.0))
    assert "noisy" in _kinds(inject_grad(noisy, seed=0)[list(noisy.columns)])


def test_add_track_in_pieces_finds_what_add_finds_of_the_whole_table() -> None:
    """The stream workers' array path: one track's fixes fed a few at a time (some
    unusable, a timestamp repeated, speed in the wrong unit, heading half the time)
    gather the same facts as :meth:`InputChecks.add` of the whole table at once."""
    rng = np.random.default_rng(3)
    n = 900
    t = np.arange(n, dtype=np.float64)
    t[100] = t[99]  # a repeated timestamp
    lat, lon = LocalFrame(48.1, 11.5).to_geodetic(
        20.0 * t + rng.normal(0, 2, n), 30.0 * np.sin(t / 40) + rng.normal(0, 2, n)
    )
    lat[200] = np.nan  # an unusable fix
    speed = np.full(n, 20.0 * 3.6)  # km/h where m/s is read
    heading = np.where(np.arange(n) % 2 == 0, 88.0, np.nan)
    whole = InputChecks().add(
        pd.DataFrame(
            {"track": "", "t": t, "lat": lat, "lon": lon, "speed": speed, "heading": heading}
        )
    )
    pieces = InputChecks()
    cuts = np.r_[0, np.sort(rng.choice(np.arange(1, n), 80, replace=False)), n]
    for a, b in itertools.pairwise(cuts):
        pieces.add_track("", t[a:b], lat[a:b], lon[a:b], speed[a:b], heading[a:b])
    assert json.dumps(pieces.to_state()) == json.dumps(whole.to_state())  # NaN as NaN
    assert pieces.findings() == whole.findings()
    assert any(kind == "reported speed" for kind, _ in whole.findings()), whole.findings()


# Fixes re-sampled onto a faster clock (the ``repeated fixes`` check).


def _repeated(fixes: pd.DataFrame, k: int) -> pd.DataFrame:
    """Each step of ``fixes`` (one track) cut into ``k`` rows that repeat its first fix:
    a logger sampling the receiver's last fix ``k`` times as often as it solves."""
    t, lat, lon = (fixes[c].to_numpy(dtype=np.float64) for c in ("t", "lat", "lon"))
    tt = np.r_[(t[:-1, None] + np.diff(t)[:, None] * (np.arange(k) / k)).ravel(), t[-1:]]
    i = np.r_[np.repeat(np.arange(len(t) - 1), k), len(t) - 1]
    return pd.DataFrame({"track": fixes["track"].iloc[0], "t": tt, "lat": lat[i], "lon": lon[i]})


def test_fixes_repeated_onto_a_faster_clock_are_named_instead_of_noise() -> None:
    """A 1 Hz drive logged at 2, 5 and 10 Hz, each fix repeated: named with the update
    period and the share of repeats, and not called a noisy receiver (its triples measure
    the leaps between updates); the drive itself, and the same drive with a straight line
    between the fixes, say nothing."""
    drive = _winding()
    assert InputChecks().add(drive).findings() == []
    for k in (2, 5, 10):
        findings = InputChecks().add(_repeated(drive, k)).findings()
        assert [kind for kind, _ in findings] == ["repeated fixes"], (k, findings)
        ((_, text),) = findings
        assert "change every 1 s" in text, text
        assert f"fixes come every {1 / k:.2g} s" in text, text
        assert f"({100 * (k - 1) / k:.0f} %)" in text, text
    t = drive["t"].to_numpy()
    tt = np.linspace(t[0], t[-1], 5 * (len(t) - 1) + 1)
    line = pd.DataFrame(
        {
            "track": "a",
            "t": tt,
            "lat": np.interp(tt, t, drive["lat"].to_numpy()),
            "lon": np.interp(tt, t, drive["lon"].to_numpy()),
        }
    )
    assert "repeated fixes" not in [kind for kind, _ in InputChecks().add(line).findings()]


def test_a_drive_with_long_stops_is_not_a_repeated_clock() -> None:
    """Stops repeat the position for minutes (a logger pinning a standing car), yet while
    the car moves every fix is new: one long interval between updates per stop, not many."""
    t = np.arange(1200.0)
    moving = (t % 400) < 150  # 150 s driving, 250 s standing, three times
    north = np.cumsum(np.where(moving, 15.0, 0.0))
    lat, lon = LocalFrame(52.0, 4.4).to_geodetic(np.zeros_like(north), north)
    fixes = pd.DataFrame({"track": "a", "t": t, "lat": lat, "lon": lon})
    checks = InputChecks().add(fixes)
    ratio, updates = checks.padded()
    assert ratio == pytest.approx(1.0, rel=0.02)
    assert updates > 400
    assert checks.position_repeats > 700
    assert checks.findings() == []


def test_repeated_fixes_in_chunks_and_through_a_stream_state_equal_the_whole_file() -> None:
    """Chunks cut anywhere (inside a run of copies too), and a state written and read back
    between them, gather the same position updates as the whole table."""
    fixes = pd.concat(
        [_repeated(_winding(), 5), _repeated(_winding(seed=1).assign(track="b"), 5)]
    ).reset_index(drop=True)
    whole = InputChecks().add(fixes)
    chunked = _through_states(fixes, 333)
    assert (whole.update_hist == chunked.update_hist).all()
    assert whole.position_repeats == chunked.position_repeats
    assert whole.findings() == chunked.findings()
    assert [kind for kind, _ in whole.findings()] == ["repeated fixes"]


def test_a_stream_state_from_before_the_check_still_loads() -> None:
    """A Redis worker's stored checks written before the position-update facts existed
    load, and the check starts from nothing there."""
    state = InputChecks().add(_repeated(_winding(), 5)).to_state()
    for key in ("update_hist", "position_repeats", "last_update"):
        del state[key]
    old = InputChecks.from_state(state)
    assert old.update_hist.sum() == 0
    assert old.position_repeats == 0
    assert "repeated fixes" not in [kind for kind, _ in old.findings()]


def test_no_real_drive_is_a_repeated_clock_or_coarse(shared_data: Path) -> None:
    """Every split of every real data set, at its own rate and decimated to 0.5 Hz: the
    positions change at the rate the fixes come (ratio 1) and are written finer than any
    coarse grid, so neither check says anything."""
    from gradgps._tracks.track import to_fixes

    checked = 0
    for name, split, cmap, data in _every_real_drive(shared_data):
        checks = InputChecks().add(to_fixes(data, cmap))
        ratio, updates = checks.padded()
        assert updates >= 300, (name, split)
        assert ratio < 1.1, (name, split, ratio)
        kinds = [k for k, _ in checks.findings()]
        assert "repeated fixes" not in kinds, (name, split)
        assert "coarse coordinates" not in kinds, (name, split)
        assert "one-fix tracks" not in kinds, (name, split)
        assert "time runs backwards" not in kinds, (name, split)
        assert checks.coarse_grid() is None, (name, split)
        checked += 1
    assert checked >= 36


def _every_real_drive(shared_data: Path) -> Iterator[tuple[str, str, Any, pd.DataFrame]]:
    """``(data set, split, column map, table)`` for every split of every real data set, at
    its own rate and decimated to 0.5 Hz."""
    from gradgps._data.datasets import DATASETS, TEST_ONLY, load_dataset
    from gradgps._eval.robustness import decimate
    from gradgps._tracks.track import to_fixes

    for name in DATASETS:
        if name == "simulated":
            continue
        for split in ("test",) if name in TEST_ONLY else ("train", "validation", "test"):
            table = load_dataset(name, split, data_dir=shared_data)
            if table.empty:
                continue
            cmap = to_fixes(table).attrs["columns"]
            for data in (table, decimate(table, cmap, 2.0)):
                yield name, split, cmap, data


# Coordinates rounded on export (the ``coarse coordinates`` check).


@pytest.mark.parametrize(
    ("rounding", "name"),
    [
        (lambda x: np.round(x, 4), "4 decimals of a degree"),
        (lambda x: np.round(x, 3), "3 decimals of a degree"),
        (
            lambda x: np.trunc(x) + np.round((x - np.trunc(x)) * 60.0, 2) / 60.0,
            "hundredths of a minute",
        ),
    ],
)
def test_coordinates_rounded_on_export_are_named_with_their_grid(
    rounding: object, name: str
) -> None:
    """A drive whose positions were written with few digits is named once, with the grid
    and the metres it moves a fix, and not also called noisy or a faster clock (the
    rounding makes both); written in full, or to 5 decimals, it says nothing (positions
    only: a witness column would be held against the rounded chords too)."""
    drive = _winding()[["track", "t", "lat", "lon"]]
    assert callable(rounding)
    coarse = drive.assign(lat=rounding(drive["lat"]), lon=rounding(drive["lon"]))
    findings = InputChecks().add(coarse).findings()
    assert [kind for kind, _ in findings] == ["coarse coordinates"], findings
    assert name in findings[0][1]
    five = drive.assign(lat=drive["lat"].round(5), lon=drive["lon"].round(5))
    assert InputChecks().add(five).findings() == []
    assert InputChecks().add(drive).findings() == []


def test_coarse_coordinates_in_chunks_and_stream_states_equal_the_whole_file() -> None:
    drive = _winding()
    coarse = drive.assign(lat=drive["lat"].round(4), lon=drive["lon"].round(4))
    whole = InputChecks().add(coarse)
    chunked = _through_states(coarse, 97)
    assert whole.fixes_seen == chunked.fixes_seen == len(coarse)
    assert (whole.on_grid == chunked.on_grid).all()
    assert whole.findings() == chunked.findings()
    state = whole.to_state()
    state["on_grid"] = [1, 2]
    with pytest.raises(ValueError, match="one count per grid"):
        InputChecks.from_state(state)


def test_a_few_fixes_on_a_grid_by_chance_say_nothing() -> None:
    """Under the share: a drive in full precision with a tenth of its fixes rounded."""
    drive = _winding()
    some = drive.index % 10 == 0
    mixed = drive.copy()
    mixed.loc[some, "lat"] = mixed.loc[some, "lat"].round(4)
    mixed.loc[some, "lon"] = mixed.loc[some, "lon"].round(4)
    assert InputChecks().add(mixed).findings() == []


def test_a_drive_that_lost_fixes_at_random_is_not_a_repeated_clock() -> None:
    """Half or more of the fixes lost at random leave steps of one, two, three periods,
    and the times between updates the same: no faster clock, however the medians of the
    two fall (they sat either side of one period before the check used quartiles); a
    padded drive that lost a tenth of its rows still is one."""
    drive = _winding(minutes=30.0)
    for seed in range(6):
        rng = np.random.default_rng(seed)
        pinned = drive.copy()  # 2 % of the fixes repeat the one before (a standing car)
        pin = np.flatnonzero(rng.random(len(drive)) < 0.02)
        pin = pin[pin > 0]
        for c in ("lat", "lon"):
            pinned.iloc[pin, pinned.columns.get_loc(c)] = drive[c].to_numpy()[pin - 1]
        for lost in (0.3, 0.5, 0.7):
            kept = pinned[rng.random(len(drive)) > lost]
            kinds = [kind for kind, _ in InputChecks().add(kept).findings()]
            assert "repeated fixes" not in kinds, (seed, lost, kinds)
    rng = np.random.default_rng(0)
    padded = _repeated(drive, 2)
    padded = padded[rng.random(len(padded)) > 0.1]
    assert "repeated fixes" in [kind for kind, _ in InputChecks().add(padded).findings()]


# A track column that numbers the rows (the ``one-fix tracks`` check).


@pytest.mark.parametrize("chunk_size", ["0", "37"])
def test_an_id_column_that_numbers_the_rows_is_named(tmp_path: Path, chunk_size: str) -> None:
    """A drive written with a row number in a column ``id`` (which the reader takes for a
    track column) is read as one track per fix, and nothing can be flagged: ``detect``
    says so once, naming the column and the flag that reads it as one track, in one pass
    and in chunks; with ``--track-col ''`` it is one track and the warning is gone."""
    from gradgps._cli import main

    drive = _winding()[["t", "lat", "lon"]]
    drive.insert(0, "id", np.arange(len(drive)))
    src = tmp_path / "with_id.csv"
    drive.to_csv(src, index=False)
    runner = CliRunner()
    out = tmp_path / "out.csv"
    result = runner.invoke(main, ["detect", str(src), "-o", str(out), "--chunk-size", chunk_size])
    assert result.exit_code == 0, result.output
    lines = [line for line in result.stderr.splitlines() if line.startswith("warning: ")]
    assert len(lines) == 1, lines
    assert "one-fix tracks" in lines[0]
    assert f"{len(drive):,} of {len(drive):,} fixes" in lines[0]
    assert "(column 'id')" in lines[0]
    assert "--track-col ''" in lines[0]
    result = runner.invoke(
        main,
        ["detect", str(src), "-o", str(out), "--chunk-size", chunk_size, "--track-col", ""],
    )
    assert result.exit_code == 0, result.output
    assert "warning" not in result.output


def test_a_fleet_of_short_tracks_is_not_one_fix_tracks() -> None:
    """Many vehicles with a few fixes each, a few with one: no warning; the same fixes fed
    in chunks and through a stream state count the same fixes per track."""
    parts = [_track(np.arange(3.0) + 10 * i, name=f"v{i}") for i in range(40)]
    parts += [_track(np.array([500.0 + i]), name=f"w{i}") for i in range(30)]
    fleet = pd.concat(parts).sort_values("t", kind="stable").reset_index(drop=True)
    whole = InputChecks().add(fleet)
    assert "one-fix tracks" not in [kind for kind, _ in whole.findings()]
    chunked = _through_states(fleet, 11)
    assert chunked.fixes_per_track == whole.fixes_per_track
    lone = pd.concat([_track(np.array([float(i)]), name=f"r{i}") for i in range(60)])
    assert [kind for kind, _ in InputChecks().add(lone).findings()] == ["one-fix tracks"]


# A file not in time order (the ``time runs backwards`` check).


def test_a_file_written_newest_first_is_named() -> None:
    """Newest first, every fix but the first comes before the one above it (each is then
    flagged invalid): named, with the count; shuffled rows too; a drive in time order with
    a few clock steps back says nothing."""
    drive = _winding()[["track", "t", "lat", "lon"]]
    findings = InputChecks().add(drive.iloc[::-1]).findings()
    assert [kind for kind, _ in findings] == ["time runs backwards"], findings
    assert f"{len(drive) - 1:,} of {len(drive):,} fixes" in findings[0][1]
    shuffled = drive.sample(frac=1.0, random_state=0)
    assert "time runs backwards" in [kind for kind, _ in InputChecks().add(shuffled).findings()]
    glitches = drive.copy()
    glitches.iloc[[100, 300, 500], glitches.columns.get_loc("t")] -= 5.0
    assert "time runs backwards" not in [k for k, _ in InputChecks().add(glitches).findings()]


def test_time_order_in_chunks_and_stream_states_equals_the_whole_file() -> None:
    """Two tracks written newest first, interleaved, fed in chunks through stored states:
    the same count as the whole table (a chunk's first fix is held against its track's
    latest time from the chunks before)."""
    a = _winding()[["track", "t", "lat", "lon"]].iloc[::-1].reset_index(drop=True)
    b = _winding(seed=1)[["track", "t", "lat", "lon"]].assign(track="b")
    both = pd.concat([a, b]).sort_index(kind="stable").reset_index(drop=True)
    whole = InputChecks().add(both)
    chunked = _through_states(both, 41)
    assert whole.backward == chunked.backward == len(a) - 1
    assert whole.findings() == chunked.findings()


def test_a_speed_column_of_zeros_is_named() -> None:
    """An export that fills the speed column with zeros: the steps it calls standing are
    left out of the agreement (a fault's fast chord while the car stands must not count),
    so before this check nothing was said; now it is named, with the flag that leaves it
    out. A real stop (speed 0 where the positions stand too) says nothing."""
    drive = _winding()
    zeros = drive.assign(speed=0.0)
    findings = InputChecks().add(zeros).findings()
    assert [kind for kind, _ in findings] == ["reported speed"], findings
    assert "placeholder" in findings[0][1]
    assert "--speed-col ''" in findings[0][1]
    # Three stops of 60 s on a straight drive at 15 m/s: the reported speed reads 0 where
    # the positions stand too.
    t = np.arange(900.0)
    v = np.where(t % 300 < 60, 0.0, 15.0)
    north = np.cumsum(v)
    lat, lon = LocalFrame(52.0, 4.4).to_geodetic(np.zeros_like(north), north)
    stopping = pd.DataFrame({"track": "a", "t": t, "lat": lat, "lon": lon, "speed": v})
    assert InputChecks().add(stopping).findings() == []


def test_injected_faults_do_not_make_the_file_checks_fire(shared_data: Path) -> None:
    """Faults are what the detector is for, not a file problem: protocol ``grad`` and
    ``gnss`` (frozen fixes, outages, drift, multipath) on every validation drive leave the
    repeated-fixes, coarse-coordinates, one-fix-tracks, time-order and placeholder-speed
    checks silent."""
    from gradgps._data.datasets import load_dataset
    from gradgps._tracks.track import to_fixes
    from gradgps.inject import inject_gnss, inject_grad

    file_kinds = {
        "repeated fixes",
        "coarse coordinates",
        "one-fix tracks",
        "time runs backwards",
    }
    for name in ("driveplotr", "tuc", "nl_motorway", "nl_motorway_gopro", "austin2006", "nevada"):
        table = load_dataset(name, "validation", data_dir=shared_data)
        cmap = to_fixes(table).attrs["columns"]
        for faults in (inject_grad, inject_gnss):
            labelled = faults(table, seed=0, columns=cmap)[list(table.columns)]
            findings = InputChecks().add(to_fixes(labelled, cmap)).findings()
            where = (name, faults.__name__, findings)
            assert not file_kinds & {kind for kind, _ in findings}, where
            assert not [text for _, text in findings if "placeholder" in text], where


# Two sources merged into one track (the ``interleaved sources`` check).


def _two_receivers(shift_s: float, gap_m: float = 4.0, noise_m: float = 0.3) -> pd.DataFrame:
    """One winding drive seen by two 1 Hz receivers ``gap_m`` m apart (east), each with
    its own noise, the second fixing ``shift_s`` s after the first (a multiple of 0.1):
    merged by time into one track."""
    fine = _winding(period_s=0.1)
    rng = np.random.default_rng(7)
    frame = LocalFrame(52.0, 4.4)
    east, north = frame.to_local(fine["lat"].to_numpy(), fine["lon"].to_numpy())
    tenths = np.rint(fine["t"].to_numpy() * 10).astype(int)
    parts = []
    for offset, gap in ((0, 0.0), (round(shift_s * 10), gap_m)):
        pick = np.flatnonzero(tenths % 10 == offset)
        lat, lon = frame.to_geodetic(
            east[pick] + gap + rng.normal(0.0, noise_m, pick.size),
            north[pick] + rng.normal(0.0, noise_m, pick.size),
        )
        parts.append(pd.DataFrame({"track": "a", "t": tenths[pick] / 10, "lat": lat, "lon": lon}))
    merged = pd.concat(parts).sort_values("t", kind="stable")
    return merged.reset_index(drop=True)


@pytest.mark.parametrize("shift_s", [0.3, 0.5, 0.7])
def test_two_receivers_merged_into_one_track_are_named(shift_s: float) -> None:
    """Fixes alternating between two receivers 4 m apart: named, with the zig-zag and the
    smooth path every other fix keeps to, instead of ``noisy fixes``; each receiver alone,
    and one receiver sampled twice as fast, say nothing."""
    findings = InputChecks().add(_two_receivers(shift_s)).findings()
    assert [kind for kind, _ in findings] == ["interleaved sources"], findings
    ((_, text),) = findings
    assert "--track-col" in text, text
    zigzag, smooth, pairs = InputChecks().add(_two_receivers(shift_s)).interleaved()
    assert zigzag > 3.0, (zigzag, smooth)
    assert smooth < 1.5, (zigzag, smooth)
    assert pairs > 1000
    for seed in (1, 2):
        assert InputChecks().add(_winding(noise_m=0.3, seed=seed)).findings() == []
    fast = _winding(period_s=0.5, noise_m=0.3)
    assert InputChecks().add(fast).findings() == []
    # Receivers that agree within their noise make no zig-zag worth a word.
    assert InputChecks().add(_two_receivers(0.5, gap_m=0.0)).findings() == []


def test_a_noisy_receiver_is_not_two_sources() -> None:
    """Independent errors move a fix as far off its predecessors' line over every other
    fix as over consecutive ones (ratio about 1, not 3): named noisy, not interleaved."""
    checks = InputChecks().add(_noisy(3.0, t=np.arange(1200.0)))
    zigzag, smooth, _ = checks.interleaved()
    assert 0.7 < zigzag / smooth < 1.4, (zigzag, smooth)
    assert [kind for kind, _ in checks.findings()] == ["noisy fixes"]


def test_interleaved_sources_in_chunks_and_stream_states_equal_the_whole_file() -> None:
    """Chunks cut anywhere, with a state written and read back between them, gather the
    same second differences over consecutive fixes and every other fix as the whole table;
    a state from before the check loads, and the check starts from nothing there."""
    fixes = _two_receivers(0.5)
    whole = InputChecks().add(fixes)
    chunked = _through_states(fixes, 97)
    assert (whole.consecutive_hist == chunked.consecutive_hist).all()
    assert (whole.alternate_hist == chunked.alternate_hist).all()
    assert (whole.second_diff_hist == chunked.second_diff_hist).all()
    assert whole.findings() == chunked.findings()
    state = whole.to_state()
    for key in ("consecutive_hist", "alternate_hist"):
        del state[key]
    old = InputChecks.from_state(state)
    assert old.interleaved()[2] == 0
    assert "interleaved sources" not in [kind for kind, _ in old.findings()]


def test_merged_real_receivers_are_named_and_real_drives_are_not(shared_data: Path) -> None:
    """The NL motorway validation trips' receivers, two by two, merged into one track
    half a second apart: every pair is named. Every real drive, every split, at its own
    rate and at 0.5 Hz, clean and with protocol ``grad`` faults: its second differences
    over consecutive fixes stay below those over every other fix (ratio under 1, where
    the check wants 3), and the check says nothing."""
    from gradgps._data.datasets import load_dataset
    from gradgps._tracks.track import to_fixes
    from gradgps.inject import inject_grad

    fixes = to_fixes(load_dataset("nl_motorway", "validation", data_dir=shared_data))
    pairs = 0
    for segment in ("00", "01"):
        here = sorted(n for n in fixes["track"].unique() if n.endswith("_" + segment))
        for a, b in itertools.combinations(here, 2):
            pair = fixes[fixes["track"].isin([a, b])]
            moved = pair.assign(t=pair["t"] + 0.5 * (pair["track"] == b), track="")
            merged = moved.sort_values("t", kind="stable").reset_index(drop=True)
            kinds = [kind for kind, _ in InputChecks().add(merged).findings()]
            assert "interleaved sources" in kinds, (a, b, kinds)
            pairs += 1
    assert pairs >= 6
    checked = 0
    for name, split, cmap, data in _every_real_drive(shared_data):
        for faults in (False, True):
            seen = inject_grad(data, seed=0, columns=cmap)[list(data.columns)] if faults else data
            checks = InputChecks().add(to_fixes(seen, cmap))
            zigzag, smooth, n = checks.interleaved()
            assert n >= 300, (name, split, n)
            assert zigzag < smooth, (name, split, faults, zigzag, smooth)
            checked += 1
    assert checked >= 72


def test_a_repeated_timestamp_at_a_new_position_is_named_even_once() -> None:
    """One fix stamped with its predecessor's time while the car moved on (a time column
    coarser than the fixes come) is named, where a repeat of the same position is not
    (under 1 % of the steps); chunks and a stream state between them count it alike, and a
    state from before the count loads with none."""
    t = REGULAR.copy()
    fixes = _track(t)
    fixes.loc[101:, "t"] -= 1.0  # fix 101 gets fix 100's time, the rest follow it
    findings = InputChecks().add(fixes).findings()
    assert [kind for kind, _ in findings] == ["repeated timestamps"], findings
    ((_, text),) = findings
    assert "1 of them at a new position" in text, text
    assert "flagged invalid in every mode" in text, text
    same = _track(t)
    same.loc[101, ["t", "lat", "lon"]] = same.loc[100, ["t", "lat", "lon"]].to_numpy()
    assert InputChecks().add(same).findings() == []
    chunked = _through_states(fixes, 101)
    assert chunked.moved_repeats == 1
    assert chunked.findings() == findings
    state = InputChecks().add(fixes).to_state()
    del state["moved_repeats"]
    assert InputChecks.from_state(state).moved_repeats == 0

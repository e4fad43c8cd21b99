"""Thresholds per sampling rate: chosen so that every group of validation drives keeps the
normal-recall floor (``gradgps._train.calibrate``), applied by the segment's period, the
same in a stream as in a batch, and overridden whole by a threshold the user gives."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from click.testing import CliRunner

from _gru_support import random_detector_model
from gradgps import ModelError, PointResult, simulate_fleet, to_fixes
from gradgps._cli import main
from gradgps._data.inject import inject_grad
from gradgps._grad.detector import Detector
from gradgps._grad.pipeline import PipelineParams, RateThresholds
from gradgps._train.calibrate import calibrate_model, recipe_group, worst_group_threshold
from gradgps._train.grad import GradTrainingSet
from gradgps._train.thresholds import recall_floor_threshold


def test_a_group_the_pool_hides_sets_the_threshold() -> None:
    """Nine groups whose normal points score low and one small group whose normal points
    score 0.7-0.8 in 5 % of cases: the pooled rule keeps the pool at 0.99 and leaves that
    group at 0.95; the worst-group rule keeps every group at the floor."""
    rng = np.random.default_rng(0)
    truth, prob, group = [], [], []
    for g in range(10):
        n = 2000 if g < 9 else 400
        normal = rng.uniform(0.0, 0.5, n)
        if g == 9:
            normal[: n // 20] = rng.uniform(0.7, 0.8, n // 20)
        faulty = rng.uniform(0.6, 1.0, n // 4)
        truth += [False] * n + [True] * (n // 4)
        prob += [*normal, *faulty]
        group += [f"g{g}"] * (n + n // 4)
    t, p, grp = np.array(truth), np.array(prob), np.array(group, dtype=object)
    pooled = recall_floor_threshold(t, p, 0.99)
    worst = worst_group_threshold(t, p, grp, 0.99)
    hidden = (grp == "g9") & ~t
    assert np.mean(p[hidden] < pooled) < 0.99  # the pool's rule fails the small group
    for g in np.unique(grp):
        normal = (grp == g) & ~t
        assert np.mean(p[normal] < worst) >= 0.99, g
    assert worst > pooled


def test_one_draw_unlike_the_others_does_not_set_the_threshold() -> None:
    """Two groups over three draws of the faults; in one draw one group's normal points
    score 0.85-0.99 in 20 % of cases (its faults fell on its hardest stretch). The median of
    the per-draw normal recalls keeps the floor without that draw's stretch: the threshold
    comes out below 0.85, where the other draws keep every group at the floor; over one
    draw's labels (every point draw 0) the same points hold it above."""
    rng = np.random.default_rng(0)
    n = 6000
    truth = rng.random(n) < 0.1
    p = np.where(truth, rng.uniform(0.5, 1.0, n), rng.uniform(0.0, 0.8, n))
    grp = np.array(["a", "b"] * (n // 2), dtype=object)
    draw = np.tile(np.repeat([0, 1, 2], 2), n // 6)
    stretch = (grp == "b") & (draw == 2) & ~truth & (rng.random(n) < 0.2)
    p[stretch] = rng.uniform(0.85, 0.99, int(stretch.sum()))
    median = worst_group_threshold(truth, p, grp, 0.99, draw)
    one_draw = worst_group_threshold(truth, p, grp, 0.99)
    assert median < 0.85 < one_draw
    for g in ("a", "b"):
        for d in (0, 1):
            normal = (grp == g) & (draw == d) & ~truth
            assert np.mean(p[normal] < median) >= 0.99, (g, d)
    assert worst_group_threshold(truth, p, grp, 0.99, np.zeros(n, np.int64)) == one_draw


def test_with_nothing_to_choose_on_the_threshold_is_one_half() -> None:
    empty = np.zeros(0)
    assert worst_group_threshold(empty.astype(bool), empty, empty.astype(object), 0.99) == 0.5


def test_a_band_applies_from_its_period_on() -> None:
    params = PipelineParams(
        threshold=0.6,
        confirm_threshold=0.7,
        rate_thresholds=(RateThresholds(1.5, 0.9, 0.95),),
    )
    assert params.thresholds_at(1.0) == (0.6, 0.7)
    assert params.thresholds_at(1.5) == (0.9, 0.95)
    assert params.thresholds_at(5.0) == (0.9, 0.95)
    plain = PipelineParams(threshold=0.6, rate_thresholds=(RateThresholds(1.5, 0.9, 0.95),))
    assert plain.thresholds_at(2.0) == (0.9, None)  # no confirm head: verdicts at once
    assert "rate_thresholds" not in params.to_dict()  # the model's thresholds, not a setting


def _with_bands(source: Path, target: Path, bands: list[dict[str, float]]) -> Path:
    shutil.copytree(source, target)
    cfg = json.loads((target / "config.json").read_text())
    cfg["thresholds"]["by_rate"] = bands
    (target / "config.json").write_text(json.dumps(cfg))
    return target


@pytest.fixture(scope="module")
def confirm_dir(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return random_detector_model(tmp_path_factory.mktemp("model"), threshold=0.5, confirm_head=True)


def _drives(hz: float) -> pd.DataFrame:
    return to_fixes(inject_grad(simulate_fleet(2, 4.0, hz, seed=11), seed=2))


def test_slow_segments_take_their_band_and_fast_ones_do_not(confirm_dir, tmp_path):
    strict = _with_bands(
        confirm_dir,
        tmp_path / "strict",
        [{"from_period_s": 1.5, "anomaly": 0.999, "confirm": 0.999}],
    )
    slow, fast = _drives(0.5), _drives(1.0)
    assert Detector(confirm_dir).detect(slow)["anomaly"].sum() > 0  # the test has teeth
    assert (
        Detector(strict).detect(slow)["anomaly"].sum()
        < Detector(confirm_dir).detect(slow)["anomaly"].sum()
    )
    pd.testing.assert_frame_equal(Detector(strict).detect(fast), Detector(confirm_dir).detect(fast))


def test_a_band_streams_as_it_batches(confirm_dir, tmp_path):
    """A stream's verdicts at once plus ``Detector.settled`` are the batch rows, with a
    band whose thresholds move verdicts (the period known only after a few fixes)."""
    banded = _with_bands(
        confirm_dir, tmp_path / "banded", [{"from_period_s": 1.5, "anomaly": 0.7, "confirm": 0.6}]
    )
    fixes = _drives(0.5)
    one = fixes[fixes["track"] == fixes["track"].iloc[0]]
    fixes = to_fixes(one[["track", "t", "lat", "lon"]].reset_index(drop=True))
    batch = Detector(banded).detect(fixes)
    assert (batch["anomaly"] != Detector(confirm_dir).detect(fixes)["anomaly"]).any()
    det = Detector(banded)
    finals: list[PointResult] = []
    last = None
    for r in fixes.itertuples(index=False):
        last = det.update(r.t, r.lat, r.lon)
        settled = det.settled
        if finals or settled is not None:
            assert settled is not None
            finals.append(settled)
    assert last is not None
    finals.append(last)
    assert [f.anomaly for f in finals] == batch["anomaly"].tolist()
    assert [f.score for f in finals] == batch["score"].tolist()


def test_a_threshold_given_holds_at_every_rate(confirm_dir, tmp_path):
    banded = _with_bands(
        confirm_dir,
        tmp_path / "given",
        [{"from_period_s": 1.5, "anomaly": 0.999, "confirm": 0.999}],
    )
    slow = _drives(0.5)
    pd.testing.assert_frame_equal(
        Detector(banded, threshold=0.4).detect(slow),
        Detector(confirm_dir, threshold=0.4).detect(slow),
    )
    assert Detector(banded, threshold=0.4).model_.params.rate_thresholds == ()


@pytest.mark.parametrize(
    "bands",
    [
        [{"from_period_s": 1.5, "anomaly": 1.5, "confirm": 0.9}],
        [{"from_period_s": -1.0, "anomaly": 0.9, "confirm": 0.9}],
        [{"anomaly": 0.9, "confirm": 0.9}],
        "slow",
    ],
)
def test_a_broken_band_is_a_clear_error(confirm_dir, tmp_path, bands):
    broken = _with_bands(confirm_dir, tmp_path / "broken", bands)  # type: ignore[arg-type]
    with pytest.raises(ModelError, match="by_rate"):
        Detector(broken)


def test_a_state_is_refused_under_other_bands(confirm_dir, tmp_path):
    banded = _with_bands(
        confirm_dir, tmp_path / "b", [{"from_period_s": 1.5, "anomaly": 0.7, "confirm": 0.6}]
    )
    det = Detector(confirm_dir)
    det.update(0.0, 41.0, -96.0)
    with pytest.raises(Exception, match=r"settings|model"):
        Detector(banded).set_state(det.get_state())


def test_calibrating_writes_bands_and_keeps_the_pooled_pair(confirm_dir, tmp_path):
    model = tmp_path / "m"
    shutil.copytree(confirm_dir, model)
    before = json.loads((model / "config.json").read_text())["thresholds"]
    tables = []
    for hz in (1.0, 0.5):
        sim = simulate_fleet(2, 3.0, hz, seed=21)
        sim["track"] = f"sim{hz:g}Hz-" + sim["track"].astype(str)
        tables.append(sim[["track", "t", "lat", "lon"]])
    spec = GradTrainingSet(seeds=(1,), val_seed=7)
    first = calibrate_model(model, tables, spec)
    assert first["pooled"] == {k: before[k] for k in ("anomaly", "confirm")}
    (band,) = first["by_rate"]  # type: ignore[misc]
    assert band["from_period_s"] == 1.5
    assert 0.0 < band["anomaly"] < 1.0
    assert 0.0 < band["confirm"] < 1.0
    # Calibrating again starts from the pooled pair: the same thresholds.
    assert calibrate_model(model, tables, spec) == first
    params = Detector(model).model_.params
    assert params.thresholds_at(2.0) == (band["anomaly"], band["confirm"])
    assert recipe_group("sim0.5Hz-3") == "sim0.5Hz"
    assert recipe_group("nevada-x@2s") == "nevada"


def test_calibrate_refuses_a_model_not_trained_on_the_recipe(confirm_dir, tmp_path):
    model = tmp_path / "m"
    shutil.copytree(confirm_dir, model)
    run = CliRunner().invoke(main, ["calibrate", str(model)])
    assert run.exit_code != 0
    assert "recipe" in run.output

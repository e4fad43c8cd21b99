"""Baselines kf, cnn, lstm-cnn, cnn-kf: kernels agree with references, NumPy with torch, stream with batch."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest
import torch
from hypothesis import given, settings
from hypothesis import strategies as st

from gradgps import LocalFrame
from gradgps._baselines.base import input_names, segments
from gradgps._baselines.cnn_kf import CnnKalmanDetector
from gradgps._baselines.kalman import KalmanDetector, KalmanParams, kf_reference, kf_segment_kernel
from gradgps._baselines.window import ARCHITECTURES, WindowClassifier, WindowModel
from gradgps._train.baselines import NETS, BaselineRecipe, train_window_model

FRAME = LocalFrame(41.25, -95.98)


def drive(n: int = 120, seed: int = 0, jump_at: int = 60) -> pd.DataFrame:
    rng = np.random.default_rng(seed)
    t = np.arange(n, dtype=float)
    east = 15.0 * t + rng.normal(0, 1.0, n)
    north = 0.02 * t**2 + rng.normal(0, 1.0, n)
    east[jump_at % n] += 80.0
    lat, lon = FRAME.to_geodetic(east, north)
    return pd.DataFrame(
        {
            "track": "a",
            "t": t,
            "lat": lat,
            "lon": lon,
            "speed": 15.0 + rng.normal(0, 0.2, n),
            "accel_x_mps2": rng.normal(0, 0.3, n),
            "gyro_z_dps": rng.normal(0, 2, n),
        }
    )


@settings(max_examples=25, deadline=None)
@given(seed=st.integers(0, 10_000), joint=st.booleans(), threshold=st.floats(0.5, 50.0))
def test_kalman_kernel_matches_reference(seed: int, joint: bool, threshold: float) -> None:
    rng = np.random.default_rng(seed)
    n, c = 60, 2 if joint else 3
    values = np.cumsum(rng.normal(0, 1, (n, c)), axis=0)
    values[rng.random((n, c)) < 0.05] = np.nan
    values[rng.integers(0, n, 4)] += 40.0
    dt = np.r_[0.0, rng.uniform(0.0, 2.0, n - 1)]
    q, r = rng.uniform(0.01, 2, c), rng.uniform(0.01, 2, c)
    forced = rng.random(n) < 0.1
    fast = kf_segment_kernel(values, dt, q, r, threshold, joint, forced)
    slow = kf_reference(values, dt, q, r, threshold, joint, forced)
    np.testing.assert_allclose(fast, slow, rtol=1e-9, atol=1e-9)


def test_kalman_flags_a_jump_and_replaces_it_by_the_prediction() -> None:
    fixes = drive()
    det = KalmanDetector.from_params(KalmanParams("position", (0.5, 0.5), (1.0, 1.0), 20.0))
    out = det.detect(fixes)
    assert out["anomaly"].iloc[60] == 1
    assert out["anomaly"].iloc[10:60].sum() == 0
    east, _ = FRAME.to_local(out["lat_clean"].iloc[60], out["lon_clean"].iloc[60])
    assert abs(float(east) - 15.0 * 60) < 10.0


@pytest.mark.parametrize("inputs", ["position", "sensor"])
def test_kalman_stream_equals_batch(inputs: str) -> None:
    fixes = drive()
    c = 2 if inputs == "position" else 3
    params = KalmanParams(inputs, (0.5,) * c, (1.0,) * c, 9.0)
    batch = KalmanDetector.from_params(params).detect(fixes)
    stream = KalmanDetector.from_params(params)
    for i, row in enumerate(fixes.itertuples(index=False)):
        if i == 50:  # checkpoint and restore mid-stream
            stream = KalmanDetector.from_params(params).set_state(stream.get_state())
        r = stream.update(
            row.t,
            row.lat,
            row.lon,
            row.speed,
            accel_x_mps2=row.accel_x_mps2,
            gyro_z_dps=row.gyro_z_dps,
        )
        assert r.anomaly == batch["anomaly"].iloc[i]
        assert r.score == pytest.approx(batch["score"].iloc[i], rel=1e-9)
        assert r.lat_clean == pytest.approx(batch["lat_clean"].iloc[i], abs=1e-9)


def _random_model(
    architecture: str, inputs: str, seed: int = 0
) -> tuple[WindowModel, torch.nn.Module]:
    torch.manual_seed(seed)
    width = 4 if inputs == "position" else 6
    net = NETS[architecture](width, 8).eval()
    weights = {k: v.detach().numpy().astype(np.float32) for k, v in net.state_dict().items()}
    assert set(weights) == set(ARCHITECTURES[architecture][0])
    model = WindowModel(
        architecture,
        inputs,
        8,
        np.zeros(width, np.float32),
        np.ones(width, np.float32),
        0.5,
        weights,
        {},
    )
    return model, net


@pytest.mark.parametrize("architecture", ["cnn", "lstm-cnn"])
def test_numpy_forward_equals_torch(architecture: str) -> None:
    model, net = _random_model(architecture, "sensor")
    x = np.random.default_rng(1).normal(0, 1, (64, 8, 6)).astype(np.float32)
    with torch.no_grad():
        expected = torch.softmax(net(torch.from_numpy(x)), -1)[:, 1].numpy()
    np.testing.assert_allclose(model.predict(x), expected, atol=1e-5)


@pytest.mark.parametrize(("architecture", "inputs"), [("cnn", "position"), ("lstm-cnn", "sensor")])
def test_window_classifier_stream_equals_batch(architecture: str, inputs: str) -> None:
    fixes = drive(60)
    fixes.loc[30:, "t"] += 100.0  # a long gap: a new segment, fresh window
    model, _ = _random_model(architecture, inputs)
    batch = WindowClassifier(model).detect(fixes)
    stream = WindowClassifier(model)
    scores = [
        stream.update(
            r.t, r.lat, r.lon, r.speed, accel_x_mps2=r.accel_x_mps2, gyro_z_dps=r.gyro_z_dps
        ).score
        for r in fixes.itertuples(index=False)
    ]
    np.testing.assert_allclose(scores, batch["score"], atol=1e-5)


def test_cnn_kf_stream_equals_batch_and_flags_the_union() -> None:
    fixes = drive(80)
    cnn, _ = _random_model("cnn", "position")
    kf = KalmanParams("position", (0.5, 0.5), (1.0, 1.0), 20.0)
    combined = CnnKalmanDetector(cnn, kf)
    batch = combined.detect(fixes)
    alone = WindowClassifier(cnn).detect(fixes)["anomaly"].to_numpy()
    assert np.all(batch["anomaly"].to_numpy() >= alone)
    stream = CnnKalmanDetector(cnn, kf)
    flags = [
        stream.update(r.t, r.lat, r.lon, r.speed).anomaly for r in fixes.itertuples(index=False)
    ]
    np.testing.assert_array_equal(flags, batch["anomaly"])


def test_window_training_learns_an_obvious_fault() -> None:
    rng = np.random.default_rng(0)
    segs, labels = [], []
    for k in range(6):
        fx = drive(100, seed=k, jump_at=0)
        truth = np.zeros(100, np.int64)
        hit = rng.choice(np.arange(5, 100), 8, replace=False)
        east, north = FRAME.to_local(fx["lat"], fx["lon"])
        east[hit] += 60.0
        fx["lat"], fx["lon"] = FRAME.to_geodetic(east, north)
        truth[hit] = 1
        s = segments(fx, "position")[0]
        segs += s
        labels += [truth[x.rows] for x in s]
    recipe = BaselineRecipe(time_budget_s=20.0, max_epochs=30, patience=30, window=8)
    model = train_window_model(
        "cnn", (segs[:4], labels[:4]), (segs[4:], labels[4:]), "position", recipe
    )
    p = np.concatenate([model.segment_probability(s) for s in segs[4:]])
    truth = np.concatenate(labels[4:]) == 1
    assert p[truth].mean() > p[~truth].mean() + 0.3


def test_channel_grad_features_are_the_position_features_plus_raw_and_consistency() -> None:
    from gradgps._baselines.channel_grad import (
        N_CROSS,
        N_RAW,
        channel_features,
        channel_signals,
        cross_names,
        feature_width,
        rema_names,
        signed_log,
    )
    from gradgps._grad.features import N_CHANNEL, FeatureParams, features_reference
    from gradgps._grad.rema import RemaParams

    fixes = drive(50)
    seg = segments(fixes, "sensor")[0][0]
    assert rema_names("sensor") == (*input_names("sensor"), "dspeed_dt_minus_accel")
    rema = (
        RemaParams(),
        RemaParams(sensitivity=4.0),
        RemaParams(alpha=0.3, slide_size=5),
        RemaParams(slide_size=20),
    )
    feats = channel_features(seg, FeatureParams(speed_heading=False), rema)
    width = N_CHANNEL + N_RAW
    assert feats.shape == (50, feature_width("sensor")) == (50, 3 * width + N_CROSS)
    for k in range(3):
        x = seg.values[:, k]
        expected = features_reference(seg.t, x, x, FeatureParams(speed_heading=False), rema[k])
        np.testing.assert_allclose(
            feats[:, k * width : k * width + N_CHANNEL],
            signed_log(np.nan_to_num(expected[:, :N_CHANNEL], nan=np.nan)),
            rtol=1e-7,
            atol=1e-7,
        )
        np.testing.assert_allclose(feats[:, k * width + N_CHANNEL], signed_log(x))
        np.testing.assert_allclose(feats[1:, k * width + N_CHANNEL + 1], signed_log(np.diff(x)))
    speed, accel = seg.values[:, 0], seg.values[:, 1]
    residual = np.diff(speed) - 0.5 * (accel[1:] + accel[:-1])
    cross = feats[:, 3 * width :]
    np.testing.assert_allclose(cross[1:, 0], signed_log(residual))
    # ... and over its robust spread: 1.4826 MAD of the previous 30 steps.
    i = 40
    spread = 1.4826 * np.median(np.abs(np.r_[0.0, residual][i - 30 : i]))
    assert cross[i, 1] == pytest.approx(signed_log(np.r_[0.0, residual][i] / spread))
    # ... and its departure from its level, the median of the previous 30 residuals.
    level = np.median(np.r_[0.0, residual][i - 30 : i])
    assert cross[i, 2] == pytest.approx(signed_log(np.r_[0.0, residual][i] - level))
    # REMA + MS-SW run on the residual too, with the residual's own REMA setting.
    r = np.r_[-accel[0], residual]  # the first step is 0: the residual is -accel there
    np.testing.assert_allclose(channel_signals(seg, "sensor")["dspeed_dt_minus_accel"], r)
    expected = features_reference(seg.t, r, r, FeatureParams(speed_heading=False), rema[3])
    np.testing.assert_allclose(
        cross[:, -N_CHANNEL:],
        signed_log(np.nan_to_num(expected[:, :N_CHANNEL], nan=np.nan)),
        rtol=1e-7,
        atol=1e-7,
    )
    # With the second speed source: reported against fix-derived speed.
    fixes["speed_fix_mps"] = fixes["speed"] + 0.5
    seg4 = segments(fixes, "sensor-fix")[0][0]
    feats4 = channel_features(
        seg4, FeatureParams(speed_heading=False), (RemaParams(),) * 7, "sensor-fix"
    )
    assert feats4.shape == (50, 4 * width + 3 * N_CROSS) == (50, feature_width("sensor-fix"))
    assert cross_names("sensor-fix")[1] == "speed_minus_speed_fix"
    mid = 0.5 * (speed[1:] + speed[:-1])
    second = feats4[:, 4 * width + N_CROSS :]
    np.testing.assert_allclose(second[1:, 0], signed_log(mid - (speed[1:] + 0.5)))


def test_channel_grad_counts_held_readings() -> None:
    from gradgps._baselines.channel_grad import ROBUST_SPAN, _held

    x = np.r_[1.0, 2.0, 2.0, 2.0, 3.0, np.full(40, 4.0)]
    held = _held(x)
    np.testing.assert_array_equal(held[:7], [0, 0, 1, 2, 0, 0, 1])
    assert held[-1] == ROBUST_SPAN  # capped


def test_recall_floor_threshold_keeps_normal_recall() -> None:
    from gradgps._train.channel_grad import recall_floor_threshold

    rng = np.random.default_rng(0)
    truth = rng.random(4000) < 0.1
    p = np.clip(np.where(truth, 0.6, 0.3) + rng.normal(0, 0.15, truth.size), 0, 1)
    t = recall_floor_threshold(truth, p, 0.995)
    assert np.mean(p[~truth] < t) >= 0.995
    assert recall_floor_threshold(truth, p, 0.5) < t  # a looser floor lets F1 decide


def test_waved_is_the_weighted_mean_of_its_members() -> None:
    from gradgps._baselines.waved import WavedDetector, WavedModel, ensemble_probability

    models = {
        name: _random_model(name, "sensor", seed)[0]
        for seed, name in enumerate(("cnn", "lstm-cnn"))
    }
    fixes = drive(40)
    det = WavedDetector(WavedModel(models["cnn"], models["lstm-cnn"], 0.3, 0.4))
    out = det.detect(fixes)
    seg = segments(fixes, "sensor")[0][0]
    expected = ensemble_probability(
        models["cnn"].segment_probability(seg), models["lstm-cnn"].segment_probability(seg), 0.3
    )
    np.testing.assert_allclose(out["score"].to_numpy()[seg.rows], expected, rtol=1e-6)
    np.testing.assert_array_equal(out["anomaly"].to_numpy()[seg.rows], expected >= 0.4)


@pytest.mark.parametrize("kind", ["kf", "cnn", "cnn-kf"])
def test_an_out_of_order_fix_is_flagged_and_changes_nothing(kind: str) -> None:
    """A fix before the previous one: invalid (was: negative time step, score < 0, clock back)."""
    cnn, _ = _random_model("cnn", "position")
    kf = KalmanParams("position", (0.5, 0.5), (1.0, 1.0), 20.0)
    det = {
        "kf": lambda: KalmanDetector.from_params(kf),
        "cnn": lambda: WindowClassifier(cnn),
        "cnn-kf": lambda: CnnKalmanDetector(cnn, kf),
    }[kind]()
    fixes = drive(10)
    for r in fixes.itertuples(index=False):
        det.update(r.t, r.lat, r.lon)
    before = det.get_state()
    back = det.update(3.0, fixes["lat"].iloc[3], fixes["lon"].iloc[3] + 1e-4)
    assert back.anomaly == 1
    assert back.invalid_reason == "time before the previous fix"
    assert np.isnan(back.score)
    assert det.get_state() == before

"""Baselines kf, cnn, lstm-cnn, cnn-kf: kernels agree with references, NumPy with torch, stream with batch."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest
import torch
from hypothesis import given, settings
from hypothesis import strategies as st

from gradgps import LocalFrame
from gradgps._baselines.base import segments
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


def test_channel_grad_features_are_the_position_features_of_each_channel() -> None:
    from gradgps._baselines.channel_grad import channel_features
    from gradgps._grad.features import N_CHANNEL, FeatureParams, features_reference
    from gradgps._grad.rema import RemaParams

    fixes = drive(50)
    seg = segments(fixes, "sensor")[0][0]
    feats = channel_features(seg, FeatureParams(speed_heading=False), RemaParams())
    assert feats.shape == (50, 3 * N_CHANNEL)
    for k in range(3):
        x = seg.values[:, k]
        expected = features_reference(seg.t, x, x, FeatureParams(speed_heading=False), RemaParams())
        np.testing.assert_allclose(
            feats[:, k * N_CHANNEL : (k + 1) * N_CHANNEL],
            expected[:, :N_CHANNEL],
            rtol=1e-7,
            atol=1e-7,
        )


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

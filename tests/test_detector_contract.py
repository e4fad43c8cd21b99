"""The detector contract (tests/_detector_checks.py) over every detector ``gradgps bench`` knows.

Trained detectors use the shipped GRAD model or small untrained networks
(seeded): the contract is about interface and consistency, not accuracy,
and untrained weights keep the suite fast.
"""

from __future__ import annotations

from collections.abc import Callable
from importlib import resources
from typing import Any

import numpy as np
import pandas as pd
import pytest

from _detector_checks import (
    BATCH_CHECKS,
    STREAM_CHECKS,
    check_batch_schema_index_and_invalid_rows,
)
from gradgps import Detector, LocalFrame, RemaDetector, SpeedGate
from gradgps._baselines.channel_grad import (
    ChannelGradDetector,
    ChannelGradModel,
    feature_width,
    rema_names,
)
from gradgps._baselines.cnn_kf import CnnKalmanDetector
from gradgps._baselines.kalman import KalmanDetector, KalmanParams
from gradgps._baselines.peers import PEER_NAMES, PeerDetector
from gradgps._baselines.rema_detector import paper_detector
from gradgps._baselines.waved import WavedDetector, WavedModel
from gradgps._baselines.window import WindowClassifier, WindowModel
from gradgps._eval.bench import DETECTOR_NAMES
from gradgps._grad.features import FeatureParams
from gradgps._grad.gru import GRUModel, weight_shapes
from gradgps._grad.rema import RemaParams
from gradgps._train.channel_grad import GRU_WINDOW

FRAME = LocalFrame(41.25, -95.98)


def _fixes(n: int = 60, seed: int = 0) -> pd.DataFrame:
    rng = np.random.default_rng(seed)
    t = 1_700_000_000.0 + np.arange(n, dtype=float)
    east = 12.0 * np.arange(n) + rng.normal(0, 1.0, n)
    north = 0.05 * np.arange(n) ** 2 + rng.normal(0, 1.0, n)
    east[n // 2] += 90.0
    lat, lon = FRAME.to_geodetic(east, north)
    return pd.DataFrame(
        {
            "track": "a",
            "t": t,
            "lat": lat,
            "lon": lon,
            "speed": 12.0 + rng.normal(0, 0.2, n),
            "speed_fix_mps": 12.0 + rng.normal(0, 0.3, n),
            "accel_x_mps2": rng.normal(0, 0.3, n),
            "gyro_z_dps": rng.normal(0, 2, n),
        }
    )


def _window_model(architecture: str, inputs: str) -> WindowModel:
    import torch

    from gradgps._train.baselines import NETS

    torch.manual_seed(0)
    width = 4 if inputs == "position" else 6
    net = NETS[architecture](width, 8).eval()
    weights = {k: v.detach().numpy().astype(np.float32) for k, v in net.state_dict().items()}
    ones = np.ones(width, np.float32)
    return WindowModel(architecture, inputs, 8, 0 * ones, ones, 0.5, weights, {})


def _channel_grad(threshold: float = 0.5, inputs: str = "sensor") -> ChannelGradDetector:
    """A channel GRAD as ``dataset_channel_grad`` builds it (window GRU), random weights."""
    rng = np.random.default_rng(0)
    width = feature_width(inputs)
    shapes = weight_shapes(width, 8, 4, 5)
    weights = {k: rng.normal(0, 0.3, s).astype(np.float32) for k, s in shapes.items()}
    gru = GRUModel(weights, np.zeros(width), np.ones(width), mode="window", window=GRU_WINDOW)
    features = FeatureParams(speed_heading=False)
    return ChannelGradDetector(
        ChannelGradModel(
            gru, threshold, features, (RemaParams(),) * len(rema_names(inputs)), inputs
        )
    )


def _waved() -> WavedDetector:
    members = (_window_model("cnn", "sensor"), _window_model("lstm-cnn", "sensor"))
    return WavedDetector(WavedModel(*members, 0.3, 0.5))


_KF = {
    "position": KalmanParams("position", (0.5, 0.5), (1.0, 1.0), 20.0),
    "sensor": KalmanParams("sensor", (0.5,) * 3, (1.0,) * 3, 9.0),
}
_DEFAULT_MODEL = resources.files("gradgps") / "models" / "default"

# bench name (and protocol where it matters) -> a maker of fresh detectors.
MAKERS: dict[str, Callable[[], Any]] = {
    "speed-gate": SpeedGate,
    "rema": RemaDetector,
    "rema-paper": paper_detector,
    "grad": lambda: Detector(str(_DEFAULT_MODEL)),
    "grad-default": Detector,
    "kf": lambda: KalmanDetector.from_params(_KF["position"]),
    "kf/sensor-grid": lambda: KalmanDetector.from_params(_KF["sensor"]),
    "cnn": lambda: WindowClassifier(_window_model("cnn", "position")),
    "cnn/sensor-grid": lambda: WindowClassifier(_window_model("cnn", "sensor")),
    "cnn-kf": lambda: CnnKalmanDetector(_window_model("cnn", "position"), _KF["position"]),
    "lstm-cnn": lambda: WindowClassifier(_window_model("lstm-cnn", "sensor")),
    "grad/sensor-grid": _channel_grad,
    "grad/sensor-grid-fix": lambda: _channel_grad(inputs="sensor-fix"),
    "grad-f1/sensor-grid": lambda: _channel_grad(threshold=0.3),
    "waved/sensor-grid": _waved,
}
# The peers (extra `peers`): batch detectors wrapping other libraries. scikit-mobility
# runs in its own virtual environment as a subprocess (tests/test_peers.py covers it).
_OWN_VENV = {"skmob-filter"}
for _peer in PEER_NAMES:
    if _peer not in _OWN_VENV:
        MAKERS[_peer] = lambda name=_peer: PeerDetector(name)


def _cases() -> list[Any]:
    cases = []
    for name, make in MAKERS.items():
        streams = hasattr(make(), "update")
        for check in BATCH_CHECKS + (STREAM_CHECKS if streams else ()):
            cases.append(pytest.param(name, check, id=f"{name}-{check.__name__}"))
    return cases


def test_every_bench_detector_is_checked() -> None:
    assert {name.split("/")[0] for name in MAKERS} | _OWN_VENV == set(DETECTOR_NAMES)


@pytest.mark.parametrize(("name", "check"), _cases())
def test_detector_contract(name: str, check: Callable[..., None]) -> None:
    check(MAKERS[name], _fixes())


def test_a_broken_policy_fails_the_check() -> None:
    """The check can fail: a detector that does not flag unusable rows breaks the contract."""

    class Lenient(SpeedGate):
        def _detect_core(self, fixes: pd.DataFrame) -> pd.DataFrame:
            out = super()._detect_core(fixes)
            out.loc[out["invalid_reason"] != "", "anomaly"] = 0
            return out

    with pytest.raises(AssertionError):
        check_batch_schema_index_and_invalid_rows(Lenient, _fixes())

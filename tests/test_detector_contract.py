"""The detector contract (tests/_detector_checks.py) over every detector ``gradgps bench`` knows.

Trained detectors use the shipped GRAD model or small untrained networks
(seeded): the contract is about interface and consistency, not accuracy,
and untrained weights keep the suite fast.
"""

from __future__ import annotations

import importlib
import inspect
import pkgutil
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
from gradgps import (
    Detector,
    FleetDetector,
    LocalFrame,
    MultiTrackDetector,
    RemaDetector,
    SpeedGate,
)
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


class _OneTrackOfMany:
    """One track of a :class:`MultiTrackDetector`: ``update`` is that track's, the state is
    the whole registry's, and ``detect`` is ``update_fixes`` on a fresh one."""

    def __init__(self) -> None:
        self.tracks = MultiTrackDetector()

    def detect(self, fixes: pd.DataFrame) -> pd.DataFrame:
        return MultiTrackDetector().update_fixes(fixes)

    def update(self, *args: Any, **kwargs: Any) -> Any:
        return self.tracks.detector("a").update(*args, **kwargs)

    def get_state(self) -> dict[str, Any]:
        return self.tracks.get_state()

    def set_state(self, state: Any) -> _OneTrackOfMany:
        self.tracks.set_state(state)
        return self


_FLEET_READINGS = ("speed", "heading", "fix_quality", "satellites")


class _OneVehicleOfAFleet:
    """One vehicle of a :class:`FleetDetector`, whose streamed verdicts must be GRAD's batch
    verdicts (``detect`` is :meth:`Detector.detect`); sensor channels are not its input."""

    def __init__(self) -> None:
        self.fleet = FleetDetector()

    def detect(self, fixes: pd.DataFrame) -> pd.DataFrame:
        return Detector().detect(fixes)

    def update(self, *fix: Any, **readings: Any) -> Any:
        kept = {k: v for k, v in readings.items() if k in _FLEET_READINGS}
        return self.fleet.update("a", *fix, **kept)

    def get_state(self) -> dict[str, Any]:
        return self.fleet.get_state("a")

    def set_state(self, state: Any) -> _OneVehicleOfAFleet:
        self.fleet.set_state("a", state)
        return self


# GRAD's many-track faces, checked through one track's view: (maker, checks). The fleet's
# batch is the Detector's, checked above; the multi-track registry's is its update_fixes.
VIEWS: dict[str, tuple[Callable[[], Any], tuple[Callable[..., None], ...]]] = {
    "grad-multi-track": (_OneTrackOfMany, BATCH_CHECKS + STREAM_CHECKS),
    "grad-fleet": (_OneVehicleOfAFleet, STREAM_CHECKS),
}


def _cases() -> list[Any]:
    cases = []
    for name, make in MAKERS.items():
        streams = hasattr(make(), "update")
        for check in BATCH_CHECKS + (STREAM_CHECKS if streams else ()):
            cases.append(pytest.param(make, check, id=f"{name}-{check.__name__}"))
    for name, (make, checks) in VIEWS.items():
        for check in checks:
            cases.append(pytest.param(make, check, id=f"{name}-{check.__name__}"))
    return cases


def test_every_bench_detector_is_checked() -> None:
    assert {name.split("/")[0] for name in MAKERS} | _OWN_VENV == set(DETECTOR_NAMES)


def _detector_classes() -> set[type]:
    """Every concrete class of gradgps's detector packages that detects: has ``detect``,
    ``update_fixes``, ``update_many`` or a stateful ``update``, is not abstract, and is not a part (a peer's stream, rema's filter, the time
    classifier, the fleet's readable reference)."""
    import gradgps._baselines
    import gradgps._grad

    parts = {"Rema", "TimeClassifier", "ReferenceFleet"}
    found: set[type] = set()
    for package in (gradgps._baselines, gradgps._grad):
        for info in pkgutil.iter_modules(package.__path__, package.__name__ + "."):
            module = importlib.import_module(info.name)
            for cls in vars(module).values():
                if (
                    isinstance(cls, type)
                    and cls.__module__.partition(".")[0] == "gradgps"  # public ones say gradgps
                    and not getattr(cls, "_is_protocol", False)
                    and not cls.__name__.startswith("_")
                    and not issubclass(cls, dict)
                    and (
                        any(hasattr(cls, m) for m in ("detect", "update_fixes", "update_many"))
                        or (hasattr(cls, "update") and hasattr(cls, "get_state"))
                    )
                    and not inspect.isabstract(cls)
                    and cls.__name__ not in parts
                    and not (cls.__name__.endswith("Stream") and cls.__module__.endswith("peers"))
                ):
                    found.add(cls)
    return found


def test_every_detector_class_is_checked() -> None:
    """A new detector class cannot slip past the suite: each one is what some maker makes
    (or the object a view wraps: the multi-track registry, the fleet)."""
    made = {type(make()) for make in MAKERS.values()}
    made |= {type(view().tracks) for view in (_OneTrackOfMany,)}
    made |= {type(_OneVehicleOfAFleet().fleet)}
    classes = _detector_classes()
    assert classes, "no detector classes found"
    assert classes <= made, f"detector classes no maker builds: {classes - made}"


@pytest.mark.parametrize(("make", "check"), _cases())
def test_detector_contract(make: Callable[[], Any], check: Callable[..., None]) -> None:
    check(make, _fixes())


def test_a_broken_policy_fails_the_check() -> None:
    """The check can fail: a detector that does not flag unusable rows breaks the contract."""

    class Lenient(SpeedGate):
        def _detect_core(self, fixes: pd.DataFrame) -> pd.DataFrame:
            out = super()._detect_core(fixes)
            out.loc[out["invalid_reason"] != "", "anomaly"] = 0
            return out

    with pytest.raises(AssertionError):
        check_batch_schema_index_and_invalid_rows(Lenient, _fixes())

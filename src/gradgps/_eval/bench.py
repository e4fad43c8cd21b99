"""Benchmarks: inject faults into a data split, run detectors, score them the same way.

Every detector is measured through its batch ``detect`` on the same
corrupted fixes (docs/architecture.md, "Detector interface"), and on the
clean fixes for false alarms. :func:`make_detector` is the one place where
benchmark names map to detectors.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Sequence
from dataclasses import replace
from pathlib import Path
from typing import TYPE_CHECKING, Any, Protocol

import numpy as np
import pandas as pd

from .._baselines.peers import PEER_NAMES
from .._data.datasets import load_dataset
from .._data.inject import (
    SENSOR_GRID_ROWS,
    inject_grad,
    inject_sensor_grid,
    with_accel_mps2,
    with_fix_speed,
)
from .._exceptions import ConfigError
from .._result import RESULT_COLUMNS
from .._tracks.track import ColumnMap, to_fixes
from .metrics import (
    class_scores,
    confusion_matrix,
    event_recall,
    false_alarms_per_hour,
    rmse_m,
    type_accuracy,
    window_scores,
)
from .scored import detect_quietly

if TYPE_CHECKING:
    from .._train.baselines import BaselineRecipe

__all__ = ["DETECTOR_NAMES", "PROTOCOLS", "Detector", "bench_units", "make_detector", "run_bench"]

PROTOCOLS = ("grad", "sensor-grid")
#: Names :func:`make_detector` knows, for help texts and error messages.
DETECTOR_NAMES = (
    "speed-gate",
    "rema",
    "rema-paper",
    "grad",
    "grad-default",
    "kf",
    "cnn",
    "cnn-kf",
    "lstm-cnn",
    "waved",
    "grad-f1",
    *PEER_NAMES,
)
_SENSOR_CHANNELS = ["accel_x_mps2", "gyro_z_dps"]
GRAD_BIAS = ("noise", "jump")
#: Window of :func:`window_scores` in the benchmark (steps; 10 for every detector).
WINDOW_STEPS = 10
GRAD_TIME = ("transient", "intermittent", "permanent")


class Detector(Protocol):
    """Anything with the batch interface: canonical fixes in, one result row per input row out."""

    def detect(self, fixes: pd.DataFrame) -> pd.DataFrame: ...


def make_detector(
    name: str,
    rema_params: Path | None = None,
    *,
    dataset: str | None = None,
    data_dir: str | Path | None = None,
    model: Path | None = None,
    protocol: str = "grad",
    recipe: BaselineRecipe | None = None,
) -> Detector:
    """A detector with its default settings, by benchmark name, for ``protocol``.

    ``rema``: :class:`RemaDetector` (trend mode), with the settings saved by
    ``gradgps tune-rema`` when ``rema_params`` names that file; ``rema-paper``:
    the literal Algorithm 1 (paper mode, paper recovery), never tuned here;
    ``grad-default``: the GRAD model shipped in the package (simulator drives
    only); ``grad``: GRAD trained on ``dataset``'s train split (the model in
    ``model`` if given, else trained once and cached, see
    :func:`gradgps._train.grad.dataset_model`).

    Under protocol ``sensor-grid`` the faults are in sensor readings, so
    ``grad`` is the channel-wise GRAD (:mod:`gradgps._baselines.channel_grad`) trained on
    ``dataset`` for that protocol (``model`` does not apply; ``grad-f1`` is
    the same model thresholded by the baselines' rule, best validation F1
    without GRAD's normal-recall floor), and the
    baselines read the sensor channels instead of positions. The baselines
    ``kf``, ``cnn``, ``cnn-kf``, ``lstm-cnn`` and ``waved`` are fitted on ``dataset``'s
    train split (validation split for stopping and thresholds) with
    ``recipe`` (default: GRAD's data, budget and stopping) and cached, see
    :mod:`gradgps._train.baselines`. The peers (:data:`PEER_NAMES`, extra
    ``peers``) use the settings tuned on ``dataset``'s validation split
    (:func:`gradgps._baselines.peers.tuned_settings`).
    """
    if name == "grad-f1" and protocol != "sensor-grid":
        raise ConfigError("detector 'grad-f1' exists under protocol sensor-grid only")
    if name in ("kf", "cnn", "cnn-kf", "lstm-cnn", "waved") or (
        name in ("grad", "grad-f1") and protocol == "sensor-grid"
    ):
        if dataset is None:
            raise ConfigError(f"detector {name!r} needs a dataset to train on")
        return _trained_baseline(name, dataset, protocol, data_dir, recipe)
    if name == "grad-default":
        from .._grad.detector import Detector as GradDetector

        return GradDetector()
    if name == "grad":
        from .._grad.detector import Detector as GradDetector

        if model is None:
            if dataset is None:
                raise ConfigError("detector 'grad' needs a dataset to train on, or a model")
            from .._train.grad import dataset_model

            model = dataset_model(dataset, data_dir)
        return GradDetector(model)
    if name in PEER_NAMES:
        from .._baselines.peers import PeerDetector, tuned_settings

        return PeerDetector(name, tuned_settings(name, dataset))
    if name == "speed-gate":
        from .._baselines.speed_gate import SpeedGate

        return SpeedGate()
    if name == "rema":
        from .._baselines.rema_detector import RemaDetector

        return RemaDetector() if rema_params is None else RemaDetector.from_file(rema_params)
    if name == "rema-paper":
        from .._baselines.rema_detector import paper_detector

        return paper_detector()
    raise ConfigError(f"unknown detector {name!r}; known detectors: {', '.join(DETECTOR_NAMES)}")


def _trained_baseline(
    name: str,
    dataset: str,
    protocol: str,
    data_dir: str | Path | None,
    recipe: BaselineRecipe | None,
) -> Detector:
    from .._train import baselines as bt

    if name == "grad":
        from .._baselines.channel_grad import ChannelGradDetector
        from .._train.channel_grad import dataset_channel_grad

        return ChannelGradDetector(dataset_channel_grad(dataset, data_dir, recipe))
    if name == "grad-f1":
        from .._baselines.channel_grad import ChannelGradDetector
        from .._train.channel_grad import dataset_channel_grad

        return ChannelGradDetector(dataset_channel_grad(dataset, data_dir, recipe, "f1"))
    if name == "waved":
        from .._baselines.waved import WavedDetector

        return WavedDetector(bt.dataset_waved(dataset, protocol, data_dir, recipe))
    if name == "kf":
        from .._baselines.kalman import KalmanDetector

        return KalmanDetector.from_params(bt.dataset_kalman(dataset, protocol, data_dir, recipe))
    if name == "cnn-kf":
        from .._baselines.cnn_kf import CnnKalmanDetector

        return CnnKalmanDetector(*bt.dataset_cnn_kf(dataset, protocol, data_dir, recipe))
    from .._baselines.window import WindowClassifier

    return WindowClassifier(bt.dataset_window_model(name, dataset, protocol, data_dir, recipe))


def _row_names(protocol: str) -> list[str]:
    if protocol == "grad":
        return ["grad"]
    if protocol == "sensor-grid":
        return [r.name for r in SENSOR_GRID_ROWS] + ["mixed"]
    raise ConfigError(f"unknown protocol {protocol!r}; choose one of {', '.join(PROTOCOLS)}")


def bench_units(protocol: str, detectors: Sequence[str]) -> int:
    """How many (row, detector) evaluations :func:`run_bench` performs (for progress bars)."""
    return len(_row_names(protocol)) * len(detectors)


def _positions(fixes: pd.DataFrame) -> np.ndarray:
    """Each row's index within its track in time order."""
    order = pd.DataFrame(
        {"track": fixes["track"].to_numpy(dtype=object), "t": fixes["t"].to_numpy(dtype=np.float64)}
    )
    order = order.sort_values(["track", "t"], kind="stable")
    pos = np.empty(len(fixes), dtype=np.int64)
    pos[order.index.to_numpy()] = order.groupby("track", sort=False).cumcount().to_numpy()
    return pos


def _check_result(name: str, result: pd.DataFrame, fixes: pd.DataFrame) -> None:
    missing = [c for c in RESULT_COLUMNS if c not in result.columns]
    if missing or len(result) != len(fixes):
        raise ConfigError(
            f"detector {name!r} broke the batch interface: expected {len(fixes)} rows with columns "
            f"{list(RESULT_COLUMNS)}, got {len(result)} rows, missing {missing}"
        )


def _scores(
    labelled: pd.DataFrame, fixes: pd.DataFrame, result: pd.DataFrame, protocol: str
) -> dict[str, Any]:
    flagged = result["anomaly"].to_numpy(dtype=np.int64) == 1
    truth = labelled["label_anomaly"].to_numpy(dtype=np.int64)
    pos = _positions(fixes)
    out: dict[str, Any] = dict(class_scores(truth, flagged))
    if protocol == "grad":
        episode = np.r_[
            labelled["label_episode_lat"].to_numpy(), labelled["label_episode_lon"].to_numpy()
        ]
        recall, delay = event_recall(episode, np.r_[flagged, flagged], np.r_[pos, pos])
        faulty = truth == 1
        out.update(
            event_recall=recall,
            detection_delay_median=delay,
            bias_type_accuracy=type_accuracy(labelled["label_bias"], result["bias_type"], flagged),
            time_type_accuracy=type_accuracy(labelled["label_time"], result["time_type"], flagged),
            recovery_rmse_m=rmse_m(
                result["lat_clean"],
                result["lon_clean"],
                labelled["lat_true"],
                labelled["lon_true"],
                faulty,
            ),
            corrupted_rmse_m=rmse_m(
                fixes["lat"], fixes["lon"], labelled["lat_true"], labelled["lon_true"], faulty
            ),
        )
        both = flagged & faulty
        for kind, labels in (("bias", GRAD_BIAS), ("time", GRAD_TIME)):
            predicted = result[f"{kind}_type"].to_numpy(dtype=object)[both]
            # Only detectors that name these types get a matrix.
            if predicted.size and set(predicted.tolist()) & set(labels):
                cm = confusion_matrix(labelled[f"label_{kind}"].to_numpy()[both], predicted, labels)
                out[f"{kind}_type_confusion"] = {
                    str(t): {str(p): int(cm.loc[t, p]) for p in cm.columns} for t in cm.index
                }
    else:
        recall, delay = event_recall(labelled["label_episode"], flagged, pos)
        out.update(
            event_recall=recall,
            detection_delay_median=delay,
            bias_type_accuracy=type_accuracy(labelled["label_type"], result["bias_type"], flagged),
            time_type_accuracy=math.nan,  # sensor-grid faults carry no time type
            recovery_rmse_m=math.nan,  # positions are not corrupted; channel recovery is not part of the interface
            corrupted_rmse_m=math.nan,
        )
    return out


def run_bench(
    protocol: str,
    dataset: str,
    detectors: Sequence[str],
    *,
    split: str = "test",
    seed: int = 0,
    scale: float = 1.0,
    data_dir: str | Path | None = None,
    advance: Callable[[str], None] | None = None,
    rema_params: Path | None = None,
    model: Path | None = None,
    recipe: BaselineRecipe | None = None,
    per_row: bool = False,
    constant: str = "stuck",
    fix_speed: bool = False,
    window: int = WINDOW_STEPS,
    rows: Sequence[str] | None = None,
) -> dict[str, Any]:
    """Run the benchmark; return the JSON-ready report (``nan`` turned into ``None``).

    ``results[detector]`` holds the scores for protocol ``grad`` and
    ``results[detector][row]`` one block per sensor-grid row (plus ``mixed``).
    ``advance`` is called after each (row, detector) evaluation.

    Under ``sensor-grid``: ``per_row`` trains (and thresholds) every trained
    detector on each row's own injection (one experiment per row, as in the
    source papers) instead of once on ``mixed``; ``constant`` is how
    ``constant`` faults are written (``stuck`` or ``offset``); ``fix_speed``
    adds the speed derived from the fixes as a second speed channel for
    every detector; ``rows`` limits the run to those rows. Every block then
    also holds ``window`` scores: :func:`window_scores` over windows of
    ``window`` steps. ``reference[row]`` holds the faulty share and the F1
    (point and window) of flagging every reading.
    """
    all_rows = _row_names(protocol)
    if rows is not None:
        unknown = [r for r in rows if r not in all_rows]
        if unknown:
            raise ConfigError(f"unknown rows {unknown}; known rows: {', '.join(all_rows)}")
        all_rows = [r for r in all_rows if r in rows]
    for name in detectors:  # bad names fail before any work
        if name not in DETECTOR_NAMES:
            raise ConfigError(
                f"unknown detector {name!r}; known detectors: {', '.join(DETECTOR_NAMES)}"
            )
    grid = protocol == "sensor-grid"
    if grid and (per_row or constant != "stuck" or fix_speed or recipe is not None):
        from .._train.baselines import BaselineRecipe as Recipe

        recipe = replace(recipe or Recipe(), constant=constant, fix_speed=fix_speed)

    def build(row_recipe: BaselineRecipe | None) -> dict[str, Detector]:
        return {
            name: make_detector(
                name,
                rema_params,
                dataset=dataset,
                data_dir=data_dir,
                model=model,
                protocol=protocol,
                recipe=row_recipe,
            )
            for name in detectors
        }

    table = load_dataset(dataset, split, data_dir=data_dir)
    cmap: ColumnMap = to_fixes(table).attrs["columns"]
    channels = _SENSOR_CHANNELS if grid else []
    if grid and fix_speed:
        table = with_fix_speed(table, cmap)
        channels = ["speed_fix_mps", *channels]
    # False alarms are counted on the uncorrupted drive.
    clean = to_fixes(with_accel_mps2(table) if grid else table, cmap, channels=channels)

    def false_alarms(built: dict[str, Detector]) -> dict[str, float]:
        out = {}
        for name, det in built.items():
            clean_result = detect_quietly(det, clean)
            _check_result(name, clean_result, clean)
            out[name] = false_alarms_per_hour(
                clean_result["anomaly"].to_numpy() == 1, clean["track"], clean["t"]
            )
        return out

    shared = None if per_row and grid else build(recipe)
    shared_alarms = None if shared is None else false_alarms(shared)
    results: dict[str, Any] = {name: {} for name in detectors}
    reference: dict[str, Any] = {}
    for row in all_rows:
        if shared is None or shared_alarms is None:
            assert recipe is not None
            built = build(replace(recipe, row=row))
            alarms = false_alarms(built)
        else:
            built, alarms = shared, shared_alarms
        if protocol == "grad":
            labelled = inject_grad(table, seed=seed, scale=scale, columns=cmap)
        else:
            labelled = inject_sensor_grid(
                table, row=row, seed=seed, scale=scale, columns=cmap, constant=constant
            )
        fixes = to_fixes(labelled, cmap, channels=channels)
        truth = labelled["label_anomaly"].to_numpy()
        # What flagging every reading scores: the floor any useful detector must clear.
        flag_all = np.ones(len(truth), bool)
        reference[row] = {
            "faulty_share": float(np.mean(truth)) if len(truth) else math.nan,
            "flag_all_f1": class_scores(truth, flag_all)["anomaly"]["f1"],
            "flag_all_window_f1": window_scores(
                truth, flag_all, fixes["track"], _positions(fixes), window
            )["anomaly"]["f1"],
        }
        for name, det in built.items():
            start = time.perf_counter()
            result = detect_quietly(det, fixes)
            elapsed = time.perf_counter() - start
            _check_result(name, result, fixes)
            block = _scores(labelled, fixes, result, protocol)
            block["window"] = window_scores(
                labelled["label_anomaly"].to_numpy(),
                result["anomaly"].to_numpy() == 1,
                fixes["track"],
                _positions(fixes),
                window,
            )
            block["window_steps"] = window
            block["false_alarms_per_hour"] = alarms[name]
            block["us_per_point"] = 1e6 * elapsed / max(len(fixes), 1)
            if protocol == "grad":
                results[name] = block
            else:
                results[name][row] = block
            if advance is not None:
                advance(f"{name} {row}")
    report = {
        "protocol": protocol,
        "dataset": dataset,
        "split": split,
        "seed": seed,
        "scale": scale,
        "per_row": bool(per_row and grid),
        "constant": constant,
        "fix_speed": bool(fix_speed),
        "window_steps": window,
        "results": results,
        "reference": reference,
    }
    jsonable: dict[str, Any] = _jsonable(report)
    return jsonable


def _jsonable(value: Any) -> Any:
    """Nested dicts with floats; ``nan``/``inf`` become ``None`` (JSON null)."""
    if isinstance(value, dict):
        return {k: _jsonable(v) for k, v in value.items()}
    if isinstance(value, (float, np.floating)):
        v = float(value)
        return v if math.isfinite(v) else None
    if isinstance(value, np.integer):
        return int(value)
    return value

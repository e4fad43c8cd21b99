"""Grid search of REMA and time-classifier parameters (paper section "Optimization Params").

The paper scores each parameter combination "using an F1 score ... for both
[normal] and [anomaly] detections". Here the score of a combination is the
**mean of the anomaly F1 and the normal F1** (macro F1) over all labelled
points of all channels pooled: anomaly F1 alone rewards flagging everything on
heavily corrupted data, normal F1 alone rewards flagging nothing; their mean
needs both. Ties are broken by the grid order (first best wins), so the result
is deterministic.

REMA is scored **per channel**, as the paper tunes it: the north metres of
each preprocessed segment against ``label_lat``, the east metres against
``label_lon`` (protocol ``grad`` corrupts the two independently). A point
made by preprocessing (an interpolated gap) has no input row and is labelled
normal. In ``trend`` mode the reported speed and heading give each channel its
expected step, exactly as in the pipeline.

The time classifier is tuned afterwards, on the flags of the whole pipeline
with the best REMA parameters: the score is the share of truly faulty,
flagged points whose time type is right (the benchmark's
``time_type_accuracy``). That costs one pipeline run plus a few hundred
compiled passes over the flags, so it is always done.

:func:`tune_on_dataset` is what ``gradgps tune-rema`` runs: inject a split,
preprocess, collect the channels, search both grids.
"""

from __future__ import annotations

import itertools
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, fields, replace
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd
from numpy.typing import ArrayLike, NDArray

from .._exceptions import ConfigError
from .._grad.rema import REMA_MODES, RemaParams, rema_batch
from .._grad.time_classifier import TIME_TYPES, TimeParams, classify_time
from .._result import f1_score

__all__ = [
    "DEFAULT_GRID",
    "DEFAULT_TIME_GRID",
    "SegmentLabels",
    "f1_scores",
    "labelled_segments",
    "tune_on_dataset",
    "tune_rema",
    "tune_time",
]

#: The paper's parameters plus ``min_margin``; ``run_growth`` and
#: ``reacquire_after`` only matter in ``trend`` mode and are dropped from the
#: grid for ``paper``. 15,360 combinations in ``trend`` mode: about 20 s on
#: driveplotr validation on one core.
DEFAULT_GRID: dict[str, tuple[object, ...]] = {
    "alpha": (0.3, 0.6),
    "alpha_min": (0.05, 0.2),
    "alpha_max": (0.9,),
    "punish": (0.05, 0.2),
    "reward": (0.02, 0.1),
    "slide_size": (4, 6, 10, 20),
    "sensitivity": (2.0, 3.0, 5.0, 8.0),
    "min_margin": (0.0, 3.0, 5.0, 8.0, 12.0),
    "run_growth": (0.0, 0.25, 0.5),
    "reacquire_after": (0, 5, 10, 20),
}

DEFAULT_TIME_GRID: dict[str, tuple[int, ...]] = {
    "permanent_run": (4, 6, 8, 10, 12, 16),
    "episode_gap": (5, 10, 15, 20, 30),
    "intermittent_bursts": (2, 3),
}


def f1_scores(pred: ArrayLike, truth: ArrayLike) -> tuple[float, float]:
    """(anomaly F1, normal F1) of 0/1 predictions (:func:`gradgps._result.f1_score`)."""
    p = np.asarray(pred).astype(bool)
    y = np.asarray(truth).astype(bool)
    return f1_score(y, p), f1_score(~y, ~p)


def _combinations(grid: Mapping[str, Sequence[object]], base: RemaParams) -> list[RemaParams]:
    names = {f.name for f in fields(RemaParams)}
    unknown = sorted(set(grid) - names)
    if unknown:
        raise ConfigError(f"unknown REMA grid keys {unknown}; choose from {sorted(names)}")
    keys = list(grid)
    out = []
    for values in itertools.product(*(grid[k] for k in keys)):
        chosen: dict[str, Any] = dict(zip(keys, values, strict=True))
        cand = replace(base, **chosen)
        if cand.alpha_min <= cand.alpha <= cand.alpha_max:
            out.append(cand.checked())
    if not out:
        raise ConfigError(
            "the REMA grid has no valid combination (need alpha_min <= alpha <= alpha_max)"
        )
    return out


def tune_rema(
    channels: Sequence[tuple[ArrayLike, ...]],
    grid: Mapping[str, Sequence[object]] | None = None,
    progress: bool = True,
    base: RemaParams | None = None,
) -> tuple[RemaParams, pd.DataFrame]:
    """Best :class:`RemaParams` on labelled channels and the table of every combination's scores.

    ``channels``: ``(values, labels)`` or ``(values, labels, known_step)``
    per channel of one segment. Parameters missing from ``grid`` come from
    ``base``. The table has one row per combination: the parameters,
    ``f1_anomaly``, ``f1_normal`` and ``score`` (their mean), sorted best first.
    """
    if not channels:
        raise ConfigError("tune_rema needs at least one (values, labels) channel")
    data = []
    for i, channel in enumerate(channels):
        if len(channel) not in (2, 3):
            raise ConfigError(
                f"channel {i}: expected (values, labels[, known_step]), got {len(channel)} items"
            )
        xa = np.asarray(channel[0], dtype=np.float64)
        ya = np.asarray(channel[1]).astype(bool)
        step = None if len(channel) == 2 else np.asarray(channel[2], dtype=np.float64)
        if xa.ndim != 1 or xa.shape != ya.shape or (step is not None and step.shape != xa.shape):
            raise ConfigError(
                f"channel {i}: values, labels (and known steps) must be 1-D of one length, "
                f"got {xa.shape}, {ya.shape}" + ("" if step is None else f", {step.shape}")
            )
        data.append((xa, ya, step))
    truth = np.concatenate([y for _, y, _ in data])
    combos = _combinations(grid if grid is not None else DEFAULT_GRID, base or RemaParams())
    rows = []
    from rich.progress import Progress

    with Progress(disable=not progress, transient=True) as bar:
        task = bar.add_task("REMA grid search", total=len(combos))
        for cand in combos:
            pred = np.concatenate([rema_batch(x, cand, step).flag for x, _, step in data])
            fa, fn = f1_scores(pred, truth)
            rows.append(
                {**cand.__dict__, "f1_anomaly": fa, "f1_normal": fn, "score": 0.5 * (fa + fn)}
            )
            bar.advance(task)
    table = pd.DataFrame(rows)
    order = np.argsort(-table["score"].to_numpy(), kind="stable")
    table = table.iloc[order].reset_index(drop=True)
    best = combos[int(order[0])]
    return best, table


def tune_time(
    flags: Sequence[ArrayLike],
    time_labels: Sequence[ArrayLike],
    grid: Mapping[str, Sequence[int]] | None = None,
) -> tuple[TimeParams, pd.DataFrame]:
    """Best :class:`TimeParams` for per-segment anomaly flags and true time types (names).

    Score: share of truly faulty and flagged points whose type is right (the
    benchmark's ``time_type_accuracy``); the table is sorted best first.
    """
    if len(flags) != len(time_labels) or not flags:
        raise ConfigError(
            "tune_time needs one true time-type array per flag array, and at least one"
        )
    truth = np.concatenate([np.asarray(y, dtype=object) for y in time_labels])
    flagged = np.concatenate([np.asarray(f).astype(bool) for f in flags])
    sel = flagged & (truth != "none")
    names = np.array(TIME_TYPES, dtype=object)
    use = grid if grid is not None else DEFAULT_TIME_GRID
    unknown = sorted(set(use) - {f.name for f in fields(TimeParams)})
    if unknown:
        raise ConfigError(
            f"unknown time grid keys {unknown}; choose from {[f.name for f in fields(TimeParams)]}"
        )
    keys = list(use)
    rows = []
    candidates = []
    for values in itertools.product(*(use[k] for k in keys)):
        cand = replace(TimeParams(), **dict(zip(keys, values, strict=True)))
        pred = np.concatenate([names[classify_time(f, cand)] for f in flags])
        accuracy = float(np.mean(pred[sel] == truth[sel])) if sel.any() else float("nan")
        rows.append({**cand.__dict__, "time_type_accuracy": accuracy})
        candidates.append(cand)
    table = pd.DataFrame(rows)
    order = np.argsort(-table["time_type_accuracy"].fillna(-1.0).to_numpy(), kind="stable")
    return candidates[int(order[0])], table.iloc[order].reset_index(drop=True)


@dataclass(frozen=True)
class SegmentLabels:
    """One preprocessed segment of an injected split: positions, steps and per-point labels."""

    period: float
    east: NDArray[np.float64]
    north: NDArray[np.float64]
    speed: NDArray[np.float64]
    heading: NDArray[np.float64]
    label_east: NDArray[np.bool_]
    label_north: NDArray[np.bool_]
    label_time: NDArray[np.object_]


def labelled_segments(
    labelled: pd.DataFrame, fixes: pd.DataFrame, max_gap_s: float = 5.0
) -> list[SegmentLabels]:
    """Preprocess injected ``fixes`` and carry the row labels of ``labelled`` over to the points.

    A point takes the labels of the input rows that map to it (any faulty row
    makes it faulty, the longest-lived time type wins); points made by
    preprocessing are normal.
    """
    from .._tracks.preprocess import preprocess

    prepared = preprocess(fixes, max_gap_s=max_gap_s)
    pts = prepared.points
    n = len(pts)
    rows = np.flatnonzero(prepared.row_point >= 0)
    target = prepared.row_point[rows]
    lab_lat = np.zeros(n, dtype=bool)
    lab_lon = np.zeros(n, dtype=bool)
    np.logical_or.at(lab_lat, target, labelled["label_lat"].to_numpy()[rows] == 1)
    np.logical_or.at(lab_lon, target, labelled["label_lon"].to_numpy()[rows] == 1)
    rank = np.zeros(n, dtype=np.int64)
    codes = (
        pd.Series(labelled["label_time"].to_numpy(dtype=object))
        .map({name: i for i, name in enumerate(TIME_TYPES)})
        .to_numpy(dtype=np.int64)
    )
    np.maximum.at(rank, target, codes[rows])
    time_names = np.array(TIME_TYPES, dtype=object)[rank]
    nan = np.full(n, np.nan)
    speed = pts["speed"].to_numpy(dtype=np.float64) if "speed" in pts.columns else nan
    heading = pts["heading"].to_numpy(dtype=np.float64) if "heading" in pts.columns else nan
    east = pts["east"].to_numpy(dtype=np.float64)
    north = pts["north"].to_numpy(dtype=np.float64)
    tracks = pts["track"].to_numpy(dtype=object)
    return [
        SegmentLabels(
            prepared.nominal_period[str(tracks[sl.start])],
            east[sl],
            north[sl],
            speed[sl],
            heading[sl],
            lab_lon[sl],
            lab_lat[sl],
            time_names[sl],
        )
        for _, sl in prepared.segment_slices()
    ]


def tune_on_dataset(
    dataset: str,
    *,
    split: str = "validation",
    seeds: Sequence[int] = (0, 1, 2),
    mode: str = "trend",
    use_speed_heading: bool = True,
    grid: Mapping[str, Sequence[object]] | None = None,
    time_grid: Mapping[str, Sequence[int]] | None = None,
    data_dir: str | Path | None = None,
    progress: bool = True,
) -> tuple[dict[str, Any], pd.DataFrame, pd.DataFrame]:
    """Tune a :class:`RemaDetector` on split ``split`` injected with protocol ``grad``.

    Each seed in ``seeds`` is one injection of the split; all are pooled, so a
    setting that is lucky on one draw of a few dozen faults does not win (a
    single validation injection picked a setting that lost track after long
    faults on the test split).

    Returns ``(settings, rema_table, time_table)``; ``settings`` is
    ``RemaDetector.to_dict()`` of the tuned detector plus a ``scores`` block,
    ready for ``RemaDetector.from_dict``. ``use_speed_heading=False`` tunes
    for streams without reported speed and heading (``paper`` mode never uses
    them).
    """
    from .._baselines.rema_detector import RemaDetector
    from .._data.datasets import load_dataset
    from .._data.inject import inject_grad
    from .._grad.core import CoreParams, core_batch
    from .._grad.features import FeatureParams, velocity_steps
    from .._tracks.track import to_fixes

    if mode not in REMA_MODES:
        raise ConfigError(f"REMA mode must be one of {REMA_MODES}, got {mode!r}")
    table = load_dataset(dataset, split, data_dir=data_dir)
    cmap = to_fixes(table).attrs["columns"]
    detector = RemaDetector(use_speed_heading=use_speed_heading and mode == "trend")
    if mode == "paper":
        detector = replace(detector, rema=RemaParams(mode="paper"))
    if not seeds:
        raise ConfigError("tune_on_dataset needs at least one injection seed")
    segments = []
    for seed in seeds:
        labelled = inject_grad(table, seed=seed, columns=cmap)
        segments += labelled_segments(
            labelled, to_fixes(labelled, cmap), max_gap_s=detector.max_gap_s
        )
    channels: list[tuple[ArrayLike, ...]] = []
    for seg in segments:
        if detector.use_speed_heading:
            step_e, step_n = velocity_steps(seg.speed, seg.heading, seg.period, seg.east.size)
        else:
            step_e = step_n = np.full(seg.east.size, np.nan)
        channels += [(seg.east, seg.label_east, step_e), (seg.north, seg.label_north, step_n)]
    use = dict(grid if grid is not None else DEFAULT_GRID)
    if mode == "paper":
        use.pop("run_growth", None)
        use.pop("reacquire_after", None)
    best, rema_table = tune_rema(channels, use, progress=progress, base=RemaParams(mode=mode))
    detector = replace(detector, rema=best)
    flags = []
    for seg in segments:
        params = CoreParams(
            period=seg.period,
            rema=best,
            features=FeatureParams(speed_heading=False),
            time=detector.time,
            recovery=detector.recovery,
            feed_recovered=detector.feed_recovered,
        )
        speed = seg.speed if detector.use_speed_heading else None
        heading = seg.heading if detector.use_speed_heading else None
        flags.append(core_batch(seg.east, seg.north, params, speed=speed, heading=heading).flag)
    best_time, time_table = tune_time(flags, [seg.label_time for seg in segments], time_grid)
    settings = replace(detector, time=best_time).to_dict()
    top = rema_table.iloc[0]
    settings["scores"] = {
        "dataset": dataset,
        "split": split,
        "seeds": list(seeds),
        "channel_f1_anomaly": float(top["f1_anomaly"]),
        "channel_f1_normal": float(top["f1_normal"]),
        "time_type_accuracy": float(time_table.iloc[0]["time_type_accuracy"]),
    }
    return settings, rema_table, time_table

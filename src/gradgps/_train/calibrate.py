"""Thresholds per sampling rate, chosen on the validation drives with the model as shipped.

Why: the network's probabilities are not calibrated alike at every rate, and
one pair of thresholds chosen on the pooled validation points (each member's
own, then averaged) let the pool hide its hardest drives. On the shipped
model's validation points (the recipe's, protocol ``grad`` seed 7, the model
run as a user runs it) the pool's normal recall at 0.5 Hz was 0.9905 while the
real drives in it were at DrivePlotR 0.981 and Austin 0.979, the simulated 0.5
Hz drives (0.997) and the faster rates carrying the pool over the floor; on the
real validation drives under another seed the 0.5 Hz normal recall was 0.976
(DrivePlotR) and 0.978 (Austin). A user's file is one drive, not the pool.

The rule, per band of sampling periods (faster than ``from_period_s``, and that
or slower): the best F1 over the band's validation points among the thresholds
that keep normal recall at the floor on *every* group of drives in the band
(each real data set, and the simulated drives at each rate), not on their
pool; where none keeps it on all, the one with the highest worst normal
recall. The anomaly head's threshold is chosen on every point's at-once
probability, the confirm head's on the reads that settle a verdict one fix
late. The points are those of :data:`CALIBRATION_DRAWS` draws of the faults over the
same drives (seeds ``val_seed``, ``val_seed + 1``, ...), and a group's normal recall at a
threshold is the median of its per-draw normal recalls: with one draw, a slow band's
threshold was held where one small group fell below the floor on that one draw, while
over five draws the same threshold kept it at 0.985-0.993
(``benchmarks/tried/results/rotated_real``); pooling the draws instead lets the larger
groups carry the smaller (``benchmarks/tried/results/gnss_passes``). Nothing here looks at
a test split.
"""

from __future__ import annotations

import json
from collections.abc import Callable, Sequence
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np
import pandas as pd

from .._data.inject import inject_freeze, inject_grad
from .._grad.detector import Detector
from .._grad.model_io import CONFIG_FILE, save_thresholds
from .._grad.pipeline import O_CONFIRM, O_SCORE, RateThresholds, segment_period
from .._result import f1_score
from .._tracks.track import to_fixes
from .grad import GradTrainingSet

__all__ = [
    "CalibrationPoints",
    "TablePoints",
    "calibrate_model",
    "calibration_points",
    "describe_thresholds",
    "inject_validation_faults",
    "recipe_group",
    "scored_normals",
    "table_points",
    "thresholds_as_trained",
    "worst_group_threshold",
]

#: Seconds between fixes from which a segment takes the slow band's thresholds:
#: between the recipe's 1 Hz and 0.5 Hz (its slowest) drives.
SLOW_FROM_PERIOD_S = 1.5
#: Draws of the validation faults the thresholds are chosen on (see the module docstring).
CALIBRATION_DRAWS = 3


def recipe_group(track: str) -> str:
    """The group of a recipe track: its source, the part of its name before the first
    ``-`` (``sim0.5Hz``, ``driveplotr``, ...; :func:`gradgps._train.recipe.recipe_tables`)."""
    return str(track).split("-", 1)[0]


def inject_validation_faults(table: pd.DataFrame, spec: GradTrainingSet) -> pd.DataFrame:
    """``table`` (one of the recipe's tables) with the validation faults injected exactly
    as training injects them: protocol ``grad`` at ``spec.val_seed``, then frozen fixes
    and stale starts where the spec has them."""
    cmap = to_fixes(table).attrs["columns"]
    labelled = inject_grad(table, seed=spec.val_seed, columns=cmap)
    if spec.freeze_share > 0 or spec.stale_start > 0:
        labelled = inject_freeze(
            labelled,
            seed=spec.val_seed,
            share=spec.freeze_share,
            stale_start=spec.stale_start,
            columns=cmap,
        )
    return labelled


@dataclass(frozen=True)
class CalibrationPoints:
    """Per point of the validation drives' segments: truth, the anomaly head's at-once
    probability, the confirm head's settling read (NaN where none), the segment's
    period (s), the point's group and the draw of the faults it comes from (0, 1, ...)."""

    truth: np.ndarray
    score: np.ndarray
    confirm: np.ndarray
    period: np.ndarray
    group: np.ndarray
    draw: np.ndarray


@dataclass(frozen=True)
class TablePoints:
    """One validation table as the calibration reads it: the table with its faults
    injected, the detector's per-point outputs and points, each point's row of the table
    (-1: none), its segment's period (s), and which points count (a row, not a stale
    start's held fix)."""

    labelled: pd.DataFrame
    out: np.ndarray
    points: pd.DataFrame
    row: np.ndarray
    period: np.ndarray
    counted: np.ndarray


def table_points(detector: Detector, table: pd.DataFrame, spec: GradTrainingSet) -> TablePoints:
    """Inject the validation faults into ``table`` exactly as training does
    (:func:`inject_validation_faults`), run ``detector`` on it and map its points back
    to rows. A stale start's held fixes do not count, as in the training loss
    (:mod:`gradgps._train.labels`)."""
    cmap = to_fixes(table).attrs["columns"]
    labelled = inject_validation_faults(table, spec)
    _, usable, prepared, out = detector._point_outputs(to_fixes(labelled, cmap))
    row_of_point = np.full(len(prepared.points), -1, np.int64)
    mapped = prepared.to_rows(
        np.arange(len(prepared.points), dtype=np.float64)[:, None], fill=-1.0
    )[:, 0]
    placed = mapped >= 0
    row_of_point[mapped[placed].astype(np.int64)] = usable[placed]
    stale_rows = (
        labelled["label_stale"].to_numpy() == 1
        if "label_stale" in labelled
        else np.zeros(len(labelled), bool)
    )
    period = np.full(len(prepared.points), np.nan)
    t = prepared.points["t"].to_numpy(np.float64)
    for _, sl in prepared.segment_slices():
        period[sl] = segment_period(t[sl])
    counted = (row_of_point >= 0) & ~stale_rows[np.maximum(row_of_point, 0)]
    return TablePoints(labelled, out, prepared.points, row_of_point, period, counted)


def calibration_points(
    detector: Detector,
    tables: Sequence[pd.DataFrame],
    spec: GradTrainingSet,
    group: Callable[[str], str] = recipe_group,
    draws: int = 1,
) -> CalibrationPoints:
    """Inject the validation faults exactly as training does (``spec.val_seed``, frozen
    fixes and stale starts; with ``draws`` > 1 also at the seeds after it), run
    ``detector`` on them and collect its per-point outputs (:func:`table_points`: a stale
    start's held fixes left out), each point marked with its draw."""
    parts: list[tuple[np.ndarray, ...]] = []
    for k, table in ((k, t) for k in range(draws) for t in tables):
        tp = table_points(detector, table, replace(spec, val_seed=spec.val_seed + k))
        keep = tp.counted
        truth_rows = tp.labelled["label_anomaly"].to_numpy() == 1
        tracks = tp.points["track"].astype(str).to_numpy()
        parts.append(
            (
                truth_rows[tp.row[keep]],
                tp.out[keep, O_SCORE],
                tp.out[keep, O_CONFIRM],
                tp.period[keep],
                np.array([group(x) for x in tracks[keep]], dtype=object),
                np.full(int(keep.sum()), k, np.int64),
            )
        )
    if not parts:
        empty = np.zeros(0)
        return CalibrationPoints(
            empty.astype(bool), empty, empty, empty, empty.astype(object), empty.astype(np.int64)
        )
    return CalibrationPoints(*(np.concatenate(c) for c in zip(*parts, strict=True)))


def scored_normals(
    truth: np.ndarray,
    probability: np.ndarray,
    group: np.ndarray,
    draw: np.ndarray | None = None,
) -> tuple[np.ndarray, np.ndarray, dict[str, np.ndarray], np.ndarray]:
    """The points that have a probability (NaN: the confirm head reads none at a
    segment's last point), their truth (bool) and probability, for each group with
    normal points among them (in order of first appearance) the mask of those points
    (what a group's normal recall is counted over), and each of those points' draw of
    the faults (``draw``; all 0 when it is None)."""
    ok = np.isfinite(probability)
    truth, probability, group = truth[ok].astype(bool), probability[ok], group[ok]
    draws = np.zeros(len(truth), np.int64) if draw is None else np.asarray(draw)[ok]
    normals: dict[str, np.ndarray] = {}
    for g in dict.fromkeys(group.tolist()):
        normal = (group == g) & ~truth
        if normal.any():
            normals[str(g)] = normal
    return truth, probability, normals, draws


def worst_group_threshold(
    truth: np.ndarray,
    probability: np.ndarray,
    group: np.ndarray,
    floor: float,
    draw: np.ndarray | None = None,
) -> float:
    """The best F1 among thresholds keeping normal recall >= ``floor`` in every group
    (else the highest worst-group normal recall; 0.5 with nothing to choose on). With
    ``draw`` (each point's draw of the faults), a group's normal recall is the median of
    its per-draw normal recalls and F1 is counted over every draw's points.

    Candidates: a grid 0.05-0.995 in steps of 0.005 and, per group, its normal
    points' probability quantiles from ``floor`` to 1 (probabilities bunch near 1).
    """
    truth, probability, normals, draws = scored_normals(truth, probability, group, draw)
    if not normals:
        return 0.5
    # per group, its normal points in each draw that has any
    per_draw = [[m & (draws == d) for d in np.unique(draws[m])] for m in normals.values()]
    candidates = [np.round(np.arange(0.05, 0.9951, 0.005), 3)]
    for normal in normals.values():
        candidates.append(
            np.nextafter(np.quantile(probability[normal], np.linspace(floor, 1.0, 51)), np.inf)
        )
    grid = np.unique(np.concatenate(candidates))
    grid = grid[(grid > 0.0) & (grid < 1.0)]
    best: tuple[bool, float, float] | None = None
    best_t = 0.5
    for t in grid:
        flagged = probability >= t
        worst = min(float(np.median([np.mean(~flagged[m]) for m in masks])) for masks in per_draw)
        holds = worst >= floor
        key = (holds, f1_score(truth, flagged) if holds else worst, -t)
        if best is None or key > best:
            best, best_t = key, float(t)
    return best_t


def thresholds_as_trained(directory: str | Path) -> dict[str, float]:
    """Write the model's thresholds as its training chose them (``thresholds.pooled``,
    or the plain pair of a model never calibrated) into its ``config.json``, at every
    rate, and return them: the network as :func:`calibrate_model` scores it before it
    chooses per-rate thresholds, and as the diagnostics read it."""
    path = Path(directory)
    thresholds = dict(json.loads((path / CONFIG_FILE).read_text())["thresholds"])
    pooled = thresholds.pop("pooled", None) or {
        k: thresholds[k] for k in ("anomaly", "confirm") if k in thresholds
    }
    save_thresholds(path, {**pooled})
    return {k: float(v) for k, v in pooled.items()}


def calibrate_model(
    directory: str | Path,
    tables: Sequence[pd.DataFrame],
    spec: GradTrainingSet,
    *,
    floor: float = 0.99,
    from_period_s: float = SLOW_FROM_PERIOD_S,
    group: Callable[[str], str] = recipe_group,
    draws: int = CALIBRATION_DRAWS,
) -> dict[str, object]:
    """Choose the model's thresholds per rate band (see the module docstring) and write
    them into its ``config.json``: ``thresholds.anomaly``/``confirm`` for segments faster
    than ``from_period_s``, ``thresholds.by_rate`` for the rest. Returns the new
    ``thresholds`` block; the members' pooled choices stay in ``thresholds.pooled``."""
    path = Path(directory)
    pooled = thresholds_as_trained(path)  # calibrate the network as trained
    points = calibration_points(Detector(path), tables, spec, group, draws)
    slow = points.period >= from_period_s
    chosen: dict[str, float] = {}
    for band, mask in (("fast", ~slow), ("slow", slow)):
        for head, values in (("anomaly", points.score), ("confirm", points.confirm)):
            if head == "confirm" and "confirm" not in pooled:
                continue
            chosen[f"{band} {head}"] = worst_group_threshold(
                points.truth[mask], values[mask], points.group[mask], floor, points.draw[mask]
            )
    new: dict[str, object] = {
        "anomaly": chosen["fast anomaly"],
        **({"confirm": chosen["fast confirm"]} if "confirm" in pooled else {}),
        "by_rate": [
            RateThresholds(
                from_period_s,
                chosen["slow anomaly"],
                chosen.get("slow confirm", chosen["slow anomaly"]),
            )
            .checked()
            .__dict__
        ],
        "rule": (
            f"per band of sampling periods (< {from_period_s:g} s, >= {from_period_s:g} s): "
            f"the best validation F1 keeping normal recall >= {floor:g} on every group of "
            f"validation drives, the median of {draws} draws of their faults "
            "(gradgps._train.calibrate)"
        ),
        "pooled": pooled,
    }
    save_thresholds(path, new)
    return new


def describe_thresholds(thresholds: dict[str, object]) -> str:
    """One line for the command line: the thresholds per rate band."""
    bands = thresholds.get("by_rate") or []
    assert isinstance(bands, list)
    confirm = thresholds.get("confirm")
    text = f"thresholds: faster fixes anomaly {thresholds['anomaly']:.3f}" + (
        f", confirm {confirm:.3f}" if isinstance(confirm, float) else ""
    )
    for band in bands:
        text += f"; every {band['from_period_s']:g} s or slower anomaly {band['anomaly']:.3f}" + (
            f", confirm {band['confirm']:.3f}" if isinstance(confirm, float) else ""
        )
    return text

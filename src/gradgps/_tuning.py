"""Grid search of REMA parameters (paper section "Optimization Params").

The paper scores each parameter combination "using an F1 score ... for both
[normal] and [anomaly] detections". Here the score of a combination is the
**mean of the anomaly F1 and the normal F1** (macro F1) over all labelled
points of all channels pooled: anomaly F1 alone rewards flagging everything on
heavily corrupted data, normal F1 alone rewards flagging nothing; their mean
needs both. Ties are broken by the grid order (first best wins), so the result
is deterministic.

Input is a list of ``(values, labels)`` pairs, one per channel of one segment
(e.g. the east and north metres of each injected segment), so the CLI wiring
(``gradgps tune-rema --protocol grad --dataset driveplotr``) is: inject,
preprocess, collect the pairs, call :func:`tune_rema`, write
``best.to_json()``.
"""

from __future__ import annotations

import itertools
from collections.abc import Mapping, Sequence
from dataclasses import fields, replace
from typing import Any

import numpy as np
import pandas as pd
from numpy.typing import ArrayLike, NDArray

from ._exceptions import ConfigError
from ._rema import RemaParams, rema_batch

__all__ = ["DEFAULT_GRID", "f1_scores", "tune_rema"]

DEFAULT_GRID: dict[str, tuple[object, ...]] = {
    "alpha": (0.3, 0.6),
    "alpha_min": (0.05, 0.2),
    "alpha_max": (0.9,),
    "punish": (0.05, 0.2),
    "reward": (0.02, 0.1),
    "slide_size": (6, 10, 20),
    "sensitivity": (2.0, 3.0, 5.0),
    "min_margin": (0.0, 2.0, 5.0),
    "mode": ("paper", "trend"),
}


def f1_scores(pred: ArrayLike, truth: ArrayLike) -> tuple[float, float]:
    """(anomaly F1, normal F1) of 0/1 predictions; F1 of a class absent from both is 1."""
    p = np.asarray(pred).astype(bool)
    y = np.asarray(truth).astype(bool)

    def f1(pp: NDArray[np.bool_], yy: NDArray[np.bool_]) -> float:
        tp = int(np.sum(pp & yy))
        denom = int(np.sum(pp)) + int(np.sum(yy))
        return 1.0 if denom == 0 else 2.0 * tp / denom

    return f1(p, y), f1(~p, ~y)


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
        raise ConfigError("the REMA grid has no valid combination (need alpha_min <= alpha <= alpha_max)")
    return out


def tune_rema(
    channels: Sequence[tuple[ArrayLike, ArrayLike]],
    grid: Mapping[str, Sequence[object]] | None = None,
    progress: bool = True,
) -> tuple[RemaParams, pd.DataFrame]:
    """Best :class:`RemaParams` on labelled channels and the table of every combination's scores.

    The table has one row per combination: the parameters, ``f1_anomaly``,
    ``f1_normal`` and ``score`` (their mean), sorted best first.
    """
    if not channels:
        raise ConfigError("tune_rema needs at least one (values, labels) channel")
    data = []
    for i, (x, y) in enumerate(channels):
        xa = np.asarray(x, dtype=np.float64)
        ya = np.asarray(y).astype(bool)
        if xa.ndim != 1 or xa.shape != ya.shape:
            raise ConfigError(f"channel {i}: values and labels must be 1-D of one length, "
                              f"got {xa.shape} and {ya.shape}")
        data.append((xa, ya))
    truth = np.concatenate([y for _, y in data])
    combos = _combinations(grid if grid is not None else DEFAULT_GRID, RemaParams())
    rows = []
    from rich.progress import Progress

    with Progress(disable=not progress, transient=True) as bar:
        task = bar.add_task("REMA grid search", total=len(combos))
        for cand in combos:
            pred = np.concatenate([rema_batch(x, cand).flag for x, _ in data])
            fa, fn = f1_scores(pred, truth)
            rows.append({**cand.__dict__, "f1_anomaly": fa, "f1_normal": fn,
                         "score": 0.5 * (fa + fn)})
            bar.advance(task)
    table = pd.DataFrame(rows)
    order = np.argsort(-table["score"].to_numpy(), kind="stable")
    table = table.iloc[order].reset_index(drop=True)
    best = combos[int(order[0])]
    return best, table

"""Benchmark metrics: how well a detector's per-point output matches injected labels.

Plain functions over NumPy arrays so they can be checked by hand and against
scikit-learn. A quantity that is undefined (precision with nothing flagged,
accuracy over no points) is ``nan``, never a made-up 0 or 1; the benchmark
writes it as JSON ``null``.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import pandas as pd
from numpy.typing import ArrayLike

from .._result import f1_score
from .._tracks.geo import haversine_m

__all__ = [
    "class_scores",
    "confusion_matrix",
    "detection_delays",
    "event_recall",
    "false_alarms_per_hour",
    "rmse_m",
    "type_accuracy",
    "window_scores",
]


def _ratio(num: int, den: int) -> float:
    return float(num) / den if den > 0 else float("nan")


def class_scores(y_true: ArrayLike, y_pred: ArrayLike) -> dict[str, dict[str, float]]:
    """Pointwise precision, recall and F1 of the anomaly (1) and the normal (0) class.

    The paper's Table 2 reports both classes; the normal class shows what
    false alarms cost, which the anomaly class alone hides when anomalies
    are rare.
    """
    t = np.asarray(y_true).astype(bool)
    p = np.asarray(y_pred).astype(bool)
    out: dict[str, dict[str, float]] = {}
    for name, positive in (("anomaly", True), ("normal", False)):
        tp = int(np.sum((t == positive) & (p == positive)))
        fp = int(np.sum((t != positive) & (p == positive)))
        fn = int(np.sum((t == positive) & (p != positive)))
        out[name] = {
            "precision": _ratio(tp, tp + fp),
            "recall": _ratio(tp, tp + fn),
            "f1": f1_score(t == positive, p == positive),
        }
    return out


def window_scores(
    y_true: ArrayLike, y_pred: ArrayLike, track: ArrayLike, position: ArrayLike, window: int
) -> dict[str, dict[str, float]]:
    """:func:`class_scores` over windows instead of points.

    Each track is cut into consecutive, non-overlapping windows of ``window``
    steps (``position`` = the step's index within its track in time order; a
    track's last window may be shorter). A window is anomalous when any of its
    steps is labelled, and flagged when any of its steps is flagged.
    """
    if int(window) != window or window < 1:
        raise ValueError(f"window must be a positive whole number of steps, got {window}")
    t = np.asarray(y_true).astype(bool)
    p = np.asarray(y_pred).astype(bool)
    codes = pd.factorize(pd.Series(np.asarray(track, dtype=object)))[0]
    block = np.asarray(position, dtype=np.int64) // int(window)
    key = pd.factorize(pd.Series(codes.astype(np.int64) * (block.max(initial=0) + 1) + block))[0]
    n = int(key.max(initial=-1)) + 1
    wt = np.zeros(n, bool)
    wp = np.zeros(n, bool)
    np.logical_or.at(wt, key, t)
    np.logical_or.at(wp, key, p)
    return class_scores(wt, wp)


def confusion_matrix(y_true: ArrayLike, y_pred: ArrayLike, labels: Sequence[str]) -> pd.DataFrame:
    """Counts of (true label, predicted label): rows true, columns predicted, in ``labels`` order.

    Pairs with a label outside ``labels`` are not counted.
    """
    t = np.asarray(y_true, dtype=object)
    p = np.asarray(y_pred, dtype=object)
    counts = np.zeros((len(labels), len(labels)), dtype=np.int64)
    for i, a in enumerate(labels):
        row = t == a
        for j, b in enumerate(labels):
            counts[i, j] = int(np.sum(row & (p == b)))
    return pd.DataFrame(
        counts,
        index=pd.Index(list(labels), name="true"),
        columns=pd.Index(list(labels), name="predicted"),
    )


def type_accuracy(true_type: ArrayLike, pred_type: ArrayLike, flagged: ArrayLike) -> float:
    """Share of truly faulty *and* flagged points whose type the detector got right.

    Conditioning on detection keeps classification separate from detection
    (a missed point is already counted in recall). ``nan`` when no faulty
    point was flagged or the detector gives no types (missing values).
    """
    t = np.asarray(true_type, dtype=object)
    p = np.asarray(pred_type, dtype=object)
    sel = (t != "none") & np.asarray(flagged).astype(bool)
    if not sel.any() or pd.isna(p[sel]).all():
        return float("nan")
    return float(np.mean(t[sel] == p[sel]))


def detection_delays(episode: ArrayLike, flagged: ArrayLike, position: ArrayLike) -> pd.DataFrame:
    """Per episode: ``found`` and ``delay`` (points from its first point to the first flag).

    ``episode`` holds an episode id per point (-1 for none), ``position`` the
    point's index within its track in time order. An episode is found when
    any of *its* points is flagged (for an intermittent fault, a burst point,
    not a normal point between bursts). ``delay`` is ``nan`` when not found.
    """
    return _detections(episode, flagged, position)[["found", "delay"]]


def _detections(episode: ArrayLike, flagged: ArrayLike, position: ArrayLike) -> pd.DataFrame:
    """:func:`detection_delays` with two more columns: ``points`` (the episode's number of
    points) and ``first_row`` (the input row of its first flagged point, the earliest row
    among equal positions; -1 when not found)."""
    ep = np.asarray(episode, dtype=np.int64)
    hit = np.asarray(flagged).astype(bool)
    pos = np.asarray(position, dtype=np.float64)
    sel = ep >= 0
    frame = pd.DataFrame(
        {"episode": ep[sel], "pos": pos[sel], "flag_pos": np.where(hit[sel], pos[sel], np.inf)}
    )
    grouped = frame.groupby("episode", sort=True).agg(
        start=("pos", "min"), first=("flag_pos", "min"), points=("pos", "size")
    )
    found = np.isfinite(grouped["first"].to_numpy())
    delay = np.where(found, grouped["first"].to_numpy() - grouped["start"].to_numpy(), np.nan)
    # Rows by episode, then flagged position (stable): each episode's first row is its first flag.
    rows, ids = np.flatnonzero(sel), ep[sel]
    order = np.lexsort((frame["flag_pos"].to_numpy(), ids))
    heads = order[np.r_[True, np.diff(ids[order]) != 0]] if order.size else order
    first_row = np.where(found, rows[heads], -1)
    return pd.DataFrame(
        {
            "found": found,
            "delay": delay,
            "points": grouped["points"].to_numpy(),
            "first_row": first_row,
        },
        index=grouped.index,
    )


def event_recall(
    episode: ArrayLike, flagged: ArrayLike, position: ArrayLike
) -> tuple[float, float]:
    """``(share of episodes found, median detection delay in points)``; nan where undefined."""
    per = detection_delays(episode, flagged, position)
    if per.empty:
        return float("nan"), float("nan")
    found = per["found"].to_numpy()
    recall = float(np.mean(found))
    delay = float(np.median(per["delay"].to_numpy()[found])) if found.any() else float("nan")
    return recall, delay


def false_alarms_per_hour(flagged: ArrayLike, track: ArrayLike, t: ArrayLike) -> float:
    """Alarms per hour of driving on data with no faults.

    An *alarm* is a run of consecutive flagged points within a track (time
    order), so one long false detection counts once, as a driver would hear
    it. Hours are the summed time spans of the tracks.
    """
    frame = pd.DataFrame(
        {
            "track": np.asarray(track, dtype=object),
            "t": np.asarray(t, dtype=np.float64),
            "flag": np.asarray(flagged).astype(bool),
        }
    )
    frame = frame[np.isfinite(frame["t"].to_numpy())].sort_values(["track", "t"], kind="stable")
    alarms = 0
    seconds = 0.0
    for _, part in frame.groupby("track", sort=False):
        f = part["flag"].to_numpy()
        alarms += int(np.sum(f & ~np.r_[False, f[:-1]]))
        tt = part["t"].to_numpy()
        seconds += float(tt.max() - tt.min())
    return alarms / (seconds / 3600.0) if seconds > 0 else float("nan")


def rmse_m(
    lat: ArrayLike,
    lon: ArrayLike,
    lat_true: ArrayLike,
    lon_true: ArrayLike,
    mask: ArrayLike | None = None,
) -> float:
    """Root mean square position error in metres over ``mask`` (all points by default).

    Points with a missing estimate count as not evaluable and are left out;
    ``nan`` when nothing is left.
    """
    d = haversine_m(lat_true, lon_true, lat, lon)
    sel = np.isfinite(d) if mask is None else np.asarray(mask).astype(bool) & np.isfinite(d)
    return float(np.sqrt(np.mean(d[sel] ** 2))) if sel.any() else float("nan")

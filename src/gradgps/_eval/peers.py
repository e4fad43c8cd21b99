"""The peers table: GRAD next to the tools users would pick instead (:mod:`gradgps._baselines.peers`).

Protocol, per data set (every shared one in :data:`gradgps._data.datasets.DATASETS`):

* **Tuning** (:func:`tune_peers`): on the *validation* split with protocol
  ``grad`` faults (seed 0), every peer runs each entry of its committed grid
  (:data:`GRIDS`) and the threshold grid (:data:`THRESHOLDS`) is swept over its
  raw score; the settings with the best anomaly F1 are kept (first on ties).
  The test split is never looked at. Results go to the committed JSON
  :data:`gradgps._baselines.peers.TUNED_FILE`.
* **Scoring** (:func:`peers_table`): on the *test* split, for the column
  variants ``positions`` (only track, t, lat, lon) and ``+speed+heading``
  (every column the data has): anomaly F1 with faults injected into the test
  split (seed 0) and, separately, into the whole file (all three splits, then
  the test rows taken); the clean false-alarm rate (percent of usable fixes
  flagged on the untouched test split); µs per fix of the batch ``detect``
  and, for the streaming peers and GRAD, of ``update`` fed one fix at a
  time; each as a ratio to GRAD (``grad-default``, the shipped model) on the
  same variant.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from .._baselines.peers import (
    DEFAULT_SETTINGS,
    PEER_NAMES,
    SKMOB_LAST_SECONDS,
    STREAMING_PEERS,
    VARIANTS,
    PeerDetector,
    peer_raw,
    peer_stream,
    threshold_of,
)
from .._data.datasets import DATASETS, SPLITS, TEST_ONLY, load_dataset
from .._data.inject import inject_grad
from .._exceptions import ConfigError
from .._tracks.track import ColumnMap, to_fixes
from .metrics import class_scores
from .scored import detect_quietly

__all__ = [
    "GRIDS",
    "PEER_DATASETS",
    "THRESHOLDS",
    "USES_REPORTED",
    "peer_datasets",
    "peers_table",
    "tune_peers",
]

#: Peers that read the reported speed/heading; the others answer the same in both variants.
USES_REPORTED = ("kalman-chi2-vel", "river-gauss", "river-hst", "pyod-iforest")
#: Data sets that are not shared real drives (no peers table on them).
_NOT_SHARED = ("simulated",)


def peer_datasets() -> tuple[str, ...]:
    """Every shared data set :func:`load_dataset` knows that has a validation split to tune
    the peers on (new names are picked up automatically; test-only sets are left out)."""
    return tuple(d for d in DATASETS if d not in _NOT_SHARED and d not in TEST_ONLY)


PEER_DATASETS = peer_datasets()


def _product(**axes: Sequence[Any]) -> list[dict[str, Any]]:
    out: list[dict[str, Any]] = [{}]
    for key, values in axes.items():
        out = [{**o, key: v} for o in out for v in values]
    return out


#: The committed tuning grid: settings that need a run of their own.
GRIDS: dict[str, list[dict[str, Any]]] = {
    "movingpandas-outlier": [{"v_max": None, "alpha": 3.0}]
    + [{"v_max": v, "alpha": 3.0} for v in (30.0, 50.0, 100.0, 200.0)],
    "movingpandas-kalman": _product(
        process_noise_std=(0.1, 0.5), measurement_noise_std=(2.0, 5.0, 20.0)
    ),
    "skmob-filter": [{"max_speed_kmh": v} for v in (30.0, 50.0, 100.0, 150.0, 200.0, 300.0, 500.0)],
    "kalman-chi2": _product(
        q=(1.0, 10.0, 100.0), r=(4.0, 25.0), gate=(0.99, 0.999, 0.99999, 0.9999999)
    ),
    "kalman-chi2-vel": _product(
        q=(1.0, 10.0, 100.0), r=(9.0,), r_vel=(0.1, 0.5, 2.0), gate=(0.999, 0.99999, 0.9999999)
    ),
    "hampel": [{"window": w} for w in (2, 3, 5, 8, 12, 20)],
    "river-gauss": _product(
        feature=("accel", "speed_gap"), window_size=(None, 60), grace_period=(2, 10)
    ),
    "river-hst": _product(window_size=(50, 250), n_trees=(10,), height=(8,)),
    "pyod-iforest": _product(
        contamination=(0.01, 0.02, 0.05, 0.1, 0.2, 0.3, 0.4), n_estimators=(100,)
    ),
}
#: Thresholds swept over one run's raw score (peers whose flag is a threshold on a score).
THRESHOLDS: dict[str, tuple[float, ...]] = {
    "movingpandas-kalman": (3.0, 5.0, 8.0, 10.0, 15.0, 20.0, 30.0, 50.0, 75.0, 100.0),
    "hampel": (1.0, 1.5, 2.0, 3.0, 4.0, 5.0, 6.0, 8.0, 10.0, 15.0, 20.0),
    "river-gauss": (0.5, 0.7, 0.8, 0.9, 0.95, 0.99, 0.995, 0.999, 0.9999),
    "river-hst": (0.3, 0.4, 0.5, 0.6, 0.7, 0.8, 0.9, 0.95, 0.99),
}


def _variant_fixes(fixes: pd.DataFrame, variant: str) -> pd.DataFrame:
    if variant == "positions":
        return fixes[["track", "t", "lat", "lon"]].copy()
    return fixes


def _has_reported(fixes: pd.DataFrame) -> bool:
    return all(
        c in fixes.columns and bool(np.isfinite(fixes[c].to_numpy(dtype=np.float64)).any())
        for c in ("speed", "heading")
    )


def _labelled(
    dataset: str, split: str, data_dir: str | Path | None, whole_file: bool, seed: int
) -> tuple[pd.DataFrame, pd.DataFrame, pd.DataFrame]:
    """(labelled table, its fixes, clean fixes) of ``split``; faults per split or whole file."""
    table = load_dataset(dataset, split, data_dir=data_dir)
    cmap: ColumnMap = to_fixes(table).attrs["columns"]
    clean = to_fixes(table, cmap)
    if not whole_file:
        labelled = inject_grad(table, seed=seed, columns=cmap)
    else:
        marker = "__gradgps_split__"
        parts = []
        for s in SPLITS:
            part = table if s == split else load_dataset(dataset, s, data_dir=data_dir)
            parts.append(part.assign(**{marker: s}))
        everything = inject_grad(pd.concat(parts, ignore_index=True), seed=seed, columns=cmap)
        keep = (everything[marker] == split).to_numpy()
        labelled = everything[keep].drop(columns=[marker]).reset_index(drop=True)
    return labelled, to_fixes(labelled, cmap), clean


def _f1(truth: np.ndarray, flagged: np.ndarray) -> float:
    return float(class_scores(truth, flagged)["anomaly"]["f1"])


def tune_peers(
    dataset: str,
    *,
    data_dir: str | Path | None = None,
    peers: Sequence[str] = PEER_NAMES,
    quick: bool = False,
    seed: int = 0,
    log: Callable[[str], None] | None = None,
) -> dict[str, dict[str, dict[str, Any]]]:
    """Best settings per variant and peer on ``dataset``'s validation split: ``{variant: {peer: settings}}``.

    ``quick`` tries only the first grid entry (a shape check, not a tuning).
    """
    labelled, fixes, _ = _labelled(dataset, "validation", data_dir, False, seed)
    truth = labelled["label_anomaly"].to_numpy(dtype=np.int64)
    variants = [v for v in VARIANTS if v == "positions" or _has_reported(fixes)]
    out: dict[str, dict[str, dict[str, Any]]] = {v: {} for v in variants}
    for peer in peers:
        for variant in variants:
            if variant != "positions" and peer not in USES_REPORTED:
                if peer in out["positions"]:
                    out[variant][peer] = out["positions"][peer]
                continue
            if variant == "positions" and peer == "kalman-chi2-vel":
                continue  # no reported velocity to measure
            began = time.perf_counter()
            best = _tune_one(peer, _variant_fixes(fixes, variant), truth, variant, quick)
            out[variant][peer] = best
            if log is not None:
                log(
                    f"tuned {peer} on {dataset}/{variant}: F1 {best['validation_f1']:.3f} "
                    f"({time.perf_counter() - began:.1f} s)"
                )
    return out


def _tune_one(
    peer: str, fixes: pd.DataFrame, truth: np.ndarray, variant: str, quick: bool
) -> dict[str, Any]:
    grid = GRIDS[peer][:1] if quick else GRIDS[peer]
    if variant == "positions" and peer == "river-gauss":
        grid = [g for g in grid if g["feature"] == "accel"]
    best: dict[str, Any] = {}
    best_f1 = -1.0
    if peer == "skmob-filter":
        from .._baselines.peers import peer_tracks
        from .._baselines.skmob_peer import skmob_kept

        tracks, _ = peer_tracks(fixes, variant)
        usable = np.concatenate([tr.rows for tr in tracks])
        kept_all, _ = skmob_kept(
            [(tr.rows, tr.t, tr.lat, tr.lon) for tr in tracks],
            [g["max_speed_kmh"] for g in grid],
        )
        for g, kept in zip(grid, kept_all, strict=True):
            flagged = np.zeros(len(fixes), bool)
            flagged[usable] = True
            flagged[kept] = False
            f1 = _f1(truth, flagged)
            if f1 > best_f1:
                best_f1, best = f1, {**DEFAULT_SETTINGS[peer], **g}
        return {**best, "validation_f1": best_f1}
    for g in grid:
        settings = {**DEFAULT_SETTINGS[peer], **g}
        raw = peer_raw(peer, fixes, settings, variant)[0]
        thresholds = THRESHOLDS.get(peer, (threshold_of(peer, settings),))
        for thr in thresholds[:1] if quick and peer in THRESHOLDS else thresholds:
            f1 = _f1(truth, raw > thr)
            if f1 > best_f1:
                best_f1 = f1
                best = {**settings, **({"threshold": thr} if peer in THRESHOLDS else {})}
    return {**best, "validation_f1": best_f1}


# ----------------------------------------------------------------------------
# The table
# ----------------------------------------------------------------------------


def _stream_us(make: Callable[[], Any], fixes: pd.DataFrame) -> float:
    """µs per fix of ``update``, one fresh stream per track, fixes in time order."""
    elapsed, count = 0.0, 0
    has_sp = "speed" in fixes.columns and "heading" in fixes.columns
    warm = make()  # compile / load the per-fix code before timing
    for r in fixes.iloc[:20].itertuples(index=False):
        warm.update(r.t, r.lat, r.lon)
    for _, rows in fixes.sort_values(["track", "t"], kind="stable").groupby("track", sort=False):
        stream = make()
        t = rows["t"].to_numpy(float)
        la = rows["lat"].to_numpy(float)
        lo = rows["lon"].to_numpy(float)
        sp = rows["speed"].to_numpy(float) if has_sp else None
        hd = rows["heading"].to_numpy(float) if has_sp else None
        began = time.perf_counter()
        if sp is None or hd is None:
            for i in range(len(t)):
                stream.update(t[i], la[i], lo[i])
        else:
            for i in range(len(t)):
                stream.update(t[i], la[i], lo[i], sp[i], hd[i])
        elapsed += time.perf_counter() - began
        count += len(t)
    return 1e6 * elapsed / max(count, 1)


def _method_row(
    name: str,
    det: Any,
    stream: Callable[[], Any] | None,
    inputs: dict[str, tuple[pd.DataFrame, pd.DataFrame]],
    clean: pd.DataFrame,
    variant: str,
) -> dict[str, Any]:
    row: dict[str, Any] = {}
    for mode, (labelled, fixes) in inputs.items():
        vf = _variant_fixes(fixes, variant)
        began = time.perf_counter()
        result = detect_quietly(det, vf)
        elapsed = time.perf_counter() - began
        flagged = result["anomaly"].to_numpy(dtype=np.int64) == 1
        scores = class_scores(labelled["label_anomaly"].to_numpy(dtype=np.int64), flagged)
        row[mode] = scores["anomaly"]
        if mode == "split":
            if name == "skmob-filter" and SKMOB_LAST_SECONDS:
                elapsed = SKMOB_LAST_SECONDS[0]  # the filter call, not its Python's start-up
            row["batch_us"] = 1e6 * elapsed / max(len(vf), 1)
            row["stream_us"] = None if stream is None else _stream_us(stream, vf)
    cf = _variant_fixes(clean, variant)
    cres = detect_quietly(det, cf)
    usable = cres["invalid_reason"].to_numpy(dtype=object) == ""
    row["clean_false_alarm_pct"] = 100.0 * float(
        np.mean(cres["anomaly"].to_numpy()[usable] == 1) if usable.any() else 0.0
    )
    return row


def peers_table(
    dataset: str,
    tuned: Mapping[str, Mapping[str, Mapping[str, Any]]],
    grad: Any,
    *,
    data_dir: str | Path | None = None,
    peers: Sequence[str] = PEER_NAMES,
    seed: int = 0,
    log: Callable[[str], None] | None = None,
) -> dict[str, Any]:
    """Scores of GRAD and every peer on ``dataset``'s test split (see the module docstring).

    ``tuned``: ``{variant: {peer: settings}}`` from :func:`tune_peers`;
    ``grad``: the GRAD detector to compare with (``gradgps.Detector()``: the shipped
    model); its class also makes the per-track streams.
    Returns ``{"points": n, "variants": {variant: {method: row}}}``.
    """
    split_l, split_f, clean = _labelled(dataset, "test", data_dir, False, seed)
    whole_l, whole_f, _ = _labelled(dataset, "test", data_dir, True, seed)
    inputs = {"split": (split_l, split_f), "whole_file": (whole_l, whole_f)}
    variants = [v for v in VARIANTS if v == "positions" or _has_reported(clean)]
    out: dict[str, Any] = {"points": len(split_f), "variants": {}}
    warm = _variant_fixes(split_f, "positions").iloc[:50]
    detect_quietly(grad, warm)  # compile and load before timing
    positions_rows: dict[str, Any] = {}
    for variant in variants:
        rows: dict[str, Any] = {}
        gstream = lambda: type(grad)(grad.model)  # noqa: E731
        rows["grad-default"] = _method_row("grad-default", grad, gstream, inputs, clean, variant)
        for peer in peers:
            if peer == "kalman-chi2-vel" and variant == "positions":
                continue
            if variant != "positions" and peer not in USES_REPORTED and peer in positions_rows:
                # reads no speed or heading: the same run as under `positions`
                rows[peer] = {**positions_rows[peer], "same_as": "positions"}
                continue
            settings = dict(tuned.get(variant, {}).get(peer, {}))
            settings.pop("validation_f1", None)
            if not settings:
                raise ConfigError(
                    f"no tuned settings for peer {peer!r} on {dataset}/{variant}; "
                    "run python benchmarks/peers.py --tune first"
                )
            det = PeerDetector(peer, {variant: settings}, variant)
            make = (
                (lambda p=peer, s=settings, v=variant: peer_stream(p, s, v))
                if peer in STREAMING_PEERS
                else None
            )
            began = time.perf_counter()
            rows[peer] = _method_row(peer, det, make, inputs, clean, variant)
            rows[peer]["settings"] = settings
            if log is not None:
                log(f"{dataset}/{variant} {peer}: {time.perf_counter() - began:.1f} s")
        g = rows["grad-default"]
        for row in rows.values():
            row["f1_ratio_to_grad"] = _ratio(row["split"]["f1"], g["split"]["f1"])
            row["batch_ratio_to_grad"] = _ratio(row["batch_us"], g["batch_us"])
            row["stream_ratio_to_grad"] = _ratio(row["stream_us"], g["stream_us"])
        out["variants"][variant] = rows
        if variant == "positions":
            positions_rows = rows
    return out


def _ratio(a: float | None, b: float | None) -> float | None:
    if a is None or b is None or not math.isfinite(a) or not math.isfinite(b) or b == 0:
        return None
    return a / b

"""``gradgps bench --protocol gnss``: the faults real receivers make, on every real test split.

Protocol ``gnss`` (:func:`gradgps._data.inject.inject_gnss`, seed 0 by
default) is injected into the test split of every real data set
(:data:`gradgps._eval.robustness.ROBUSTNESS_DATASETS`), and one detector runs
on two column variants of each:

* ``positions``: track, t, lat, lon only. An outage is then visible only
  through its positions (frozen, or missing: a missing position is an invalid
  fix and always flagged);
* ``+columns``: every column the detector reads that the labelled table has
  (speed, heading, altitude where the file has them, left true) plus the
  receiver's ``fix_quality``, ``satellites`` and ``hdop``, which the outage
  writes (added to files that had none, empty outside outages).

Per cell, over the rows with ``glitch`` = 0 (a file's real glitches have no
truth to score against), for every bias type (``noise``, ``jump``,
``freeze``, ``drift``, ``multipath``, ``outage``):

* ``recall``: share of the type's rows flagged (``anomaly`` = 1);
* ``event_recall``: share of its episodes (``label_episode``) with at least
  one flagged row, and ``delay_median_s``: over found episodes, the median
  time from the episode's first fix to its first flagged fix;
* ``precision``: share of the rows the detector flagged *and typed* as this
  type that truly are; the detector's type of a row is its ``bias_type``,
  except a fix it refused because the receiver reported no fix, whose type is
  ``outage``. ``None`` where the detector never names the type (the shipped
  model's bias head knows none, noise, jump and freeze only; ``drift`` comes
  from the drift witness, :mod:`gradgps._grad.drift`, where the input has
  speed and heading).

For ``drift`` also per found episode the offset of the position from the
truth at its first flagged fix (``label_offset_m``, metres) and the delay
(seconds): medians as ``offset_at_detection_median_m`` and
``delay_median_s``, and the episodes themselves under ``drift_episodes``.
Overall: anomaly and normal precision/recall/F1 and bias-type accuracy on
detected faults (same typing).
"""

from __future__ import annotations

import time
from typing import Any, Unpack

import numpy as np
import pandas as pd

from .._data.inject import BIAS_TYPES, GNSS_TYPES, inject_gnss
from .._result import NO_FIX, NO_SATELLITES
from .._tracks.track import ColumnMap, to_fixes
from .metrics import _detections, class_scores, type_accuracy
from .robustness import (
    Detector,
    SuiteOptions,
    machine,
    plain_json,
    report_head,
    suite_tables,
)
from .scored import detect_quietly

__all__ = ["GNSS_BIAS", "GNSS_VARIANTS", "gnss_cell", "gnss_markdown", "run_gnss_bench"]

GNSS_VARIANTS = ("positions", "+columns")
#: Every bias type of protocol ``gnss``, in report order.
GNSS_BIAS = (*BIAS_TYPES, *GNSS_TYPES)
_RECEIVER_REASONS = (NO_FIX, NO_SATELLITES)


def _variant(labelled: pd.DataFrame, full: ColumnMap, variant: str) -> tuple[list[str], ColumnMap]:
    """The columns of ``variant`` and the column map reading them."""
    assert full.time is not None
    assert full.lat is not None
    assert full.lon is not None
    core = [c for c in (full.track, full.time, full.lat, full.lon) if c]
    if variant == "positions":
        cmap = ColumnMap(
            time=full.time,
            lat=full.lat,
            lon=full.lon,
            track=full.track or "",
            speed="",
            heading="",
            alt="",
            hdop="",
            fix_quality="",
            satellites="",
        )
        return core, cmap
    roles = {
        role: getattr(full, role)
        for role in ("speed", "heading", "alt", "hdop", "fix_quality", "satellites")
    }
    extra = [c for c in roles.values() if c]
    return core + extra, ColumnMap(
        time=full.time,
        lat=full.lat,
        lon=full.lon,
        track=full.track or "",
        **{k: v or "" for k, v in roles.items()},
    )


def _predicted_types(result: pd.DataFrame) -> np.ndarray:
    """The detector's type of each row: its ``bias_type``; ``outage`` where it refused the fix
    because the receiver reported no fix."""
    kinds = result["bias_type"].to_numpy(dtype=object).copy()
    reason = result["invalid_reason"].fillna("").to_numpy(dtype=object)
    kinds[np.isin(reason, _RECEIVER_REASONS)] = "outage"
    return kinds


def _episodes(
    episode: np.ndarray, hit: np.ndarray, t: np.ndarray, offset: np.ndarray
) -> pd.DataFrame:
    """Per episode (ids >= 0): found, delay (s) and the offset (m) at the first flagged fix
    (:func:`gradgps.metrics.detection_delays` over time)."""
    per = _detections(episode, hit, t)
    rows = [
        {
            "episode": int(ep),
            "fixes": int(points),
            "found": bool(found),
            "delay_s": float(delay) if found else None,
            "offset_at_detection_m": float(offset[first]) if found else None,
        }
        for ep, points, found, delay, first in zip(
            per.index,
            per["points"],
            per["found"],
            per["delay"],
            per["first_row"],
            strict=True,
        )
    ]
    return pd.DataFrame(
        rows, columns=["episode", "fixes", "found", "delay_s", "offset_at_detection_m"]
    )


def _median(values: pd.Series) -> float | None:
    v = pd.to_numeric(values, errors="coerce").dropna()
    return float(np.median(v)) if len(v) else None


def gnss_cell(
    det: Detector, labelled: pd.DataFrame, cols: list[str], cmap: ColumnMap
) -> dict[str, Any]:
    """Score ``det`` on one variant (``cols`` read by ``cmap``) of a ``gnss``-labelled table."""
    started = time.perf_counter()
    fixes = to_fixes(labelled[cols], cmap)
    result = detect_quietly(det, fixes)
    scored = (
        labelled["glitch"].to_numpy(dtype=np.int64) != 1
        if "glitch" in labelled.columns
        else np.ones(len(labelled), dtype=bool)
    )
    hit = result["anomaly"].to_numpy(dtype=np.int64) == 1
    bias = labelled["label_bias"].to_numpy(dtype=object)
    truth = bias != "none"
    episode = labelled["label_episode"].to_numpy(dtype=np.int64)
    offset = labelled["label_offset_m"].to_numpy(dtype=np.float64)
    t = fixes["t"].to_numpy(dtype=np.float64)
    predicted = _predicted_types(result)
    out: dict[str, Any] = {
        "rows": int(scored.sum()),
        "faulty_rows": int((truth & scored).sum()),
        **class_scores(truth[scored], hit[scored]),
        "bias_type_accuracy": type_accuracy(bias[scored], predicted[scored], hit[scored]),
    }
    types: dict[str, Any] = {}
    for kind in GNSS_BIAS:
        rows = (bias == kind) & scored
        typed = hit & (predicted == kind) & scored
        per = _episodes(episode[rows], hit[rows], t[rows], offset[rows])
        entry: dict[str, Any] = {
            "rows": int(rows.sum()),
            "episodes": len(per),
            "recall": float(hit[rows].mean()) if rows.any() else None,
            "event_recall": float(per["found"].mean()) if len(per) else None,
            "precision": float((bias[typed] == kind).mean()) if typed.any() else None,
            "delay_median_s": _median(per["delay_s"]),
        }
        if kind == "drift":
            entry["offset_at_detection_median_m"] = _median(per["offset_at_detection_m"])
            entry["drift_episodes"] = per.to_dict(orient="records")
        types[kind] = entry
    out["types"] = types
    out["seconds"] = time.perf_counter() - started
    return out


def run_gnss_bench(
    det: Detector,
    detector: str,
    *,
    seed: int = 0,
    scale: float = 1.0,
    **options: Unpack[SuiteOptions],
) -> dict[str, Any]:
    """Run ``det`` on every data set's test split under protocol ``gnss``; JSON-ready report.

    ``seed`` and ``scale`` go to :func:`gradgps._data.inject.inject_gnss`;
    ``options``: :class:`gradgps._eval.robustness.SuiteOptions`.
    """
    advance = options.get("advance")
    began = time.perf_counter()
    cells: list[dict[str, Any]] = []
    for name, table in suite_tables(options, "has no real test split for protocol gnss"):
        labelled = inject_gnss(table, seed=seed, scale=scale)
        full: ColumnMap = to_fixes(labelled).attrs["columns"]
        for variant in GNSS_VARIANTS:
            cols, cmap = _variant(labelled, full, variant)
            cell = {"dataset": name, "variant": variant, "columns": cols}
            cell.update(gnss_cell(det, labelled, cols, cmap))
            cells.append(cell)
            if advance is not None:
                advance(f"{name} {variant}")
    report = {
        **report_head("protocol", "gnss", detector, options, seed, scale=scale),
        "machine": machine(),
        "seconds": time.perf_counter() - began,
        "cells": cells,
    }
    return plain_json(report)


def _num(v: float | None, digits: int = 3) -> str:
    return "-" if v is None else f"{v:.{digits}f}"


def gnss_markdown(report: dict[str, Any], command: str) -> list[str]:
    """The report as Markdown lines: per cell, one row per bias type."""
    lines = [
        f"### Protocol `gnss`: `{report['detector']}` on real drives, test splits",
        "",
        f"Command: `{command}`. Machine: {report['machine']}; wall time "
        f"{report['seconds']:.0f} s; seed {report['seed']}."
        + (f" Model: `{report['model']}`." if report["model"] else ""),
        "",
        "Recall over the type's fixes; event recall over its episodes; precision over the fixes "
        "the detector typed so (`-`: it never names the type); delay: median seconds from an "
        "episode's first fix to its first flag. Definitions: `src/gradgps/_eval/gnss.py`.",
        "",
        "| data set | columns | rows | anomaly P / R / F1 | normal R | bias acc | "
        + " | ".join(GNSS_BIAS)
        + " | drift offset at detection m |",
        "|---|---|---|---|---|---|" + "---|" * len(GNSS_BIAS) + "---|",
    ]
    for c in report["cells"]:
        a, n = c["anomaly"], c["normal"]
        per = []
        for kind in GNSS_BIAS:
            e = c["types"][kind]
            if not e["episodes"]:
                per.append("-")
                continue
            per.append(
                f"R {_num(e['recall'], 2)}, evt {_num(e['event_recall'], 2)} of "
                f"{e['episodes']}, P {_num(e['precision'], 2)}, {_num(e['delay_median_s'], 1)} s"
            )
        lines.append(
            f"| {c['dataset']} | {c['variant']} | {c['rows']:,} | "
            f"{_num(a['precision'])} / {_num(a['recall'])} / {_num(a['f1'])} | "
            f"{_num(n['recall'])} | {_num(c['bias_type_accuracy'])} | "
            + " | ".join(per)
            + f" | {_num(c['types']['drift'].get('offset_at_detection_median_m'), 1)} |"
        )
    return [*lines, "", *_drift_episode_lines(report)]


def _drift_episode_lines(report: dict[str, Any]) -> list[str]:
    """Per drift episode of each cell: the offset from the truth at its first flag (m) and
    the delay (s), the two numbers a spoofing user asks for (``missed`` where never flagged)."""
    lines = [
        "Drift episodes, each as offset at the first flag (m) @ delay (s), in episode order:",
        "",
        "| data set | columns | found | episodes |",
        "|---|---|---|---|",
    ]
    for c in report["cells"]:
        episodes = c["types"]["drift"].get("drift_episodes") or []
        if not episodes:
            continue
        shown = [
            f"{e['offset_at_detection_m']:.1f} m @ {e['delay_s']:.0f} s" if e["found"] else "missed"
            for e in episodes
        ]
        found = sum(bool(e["found"]) for e in episodes)
        lines.append(
            f"| {c['dataset']} | {c['variant']} | {found} of {len(episodes)} | {', '.join(shown)} |"
        )
    return [*lines, ""]

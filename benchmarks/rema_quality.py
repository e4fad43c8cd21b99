"""REMA-only detection F1 and recovery RMSE on a self-made injection into real drives.

Not the project's injection protocol (another module): a small stand-in with
the protocol's time shapes, so REMA modes can be compared now. Each
preprocessed segment of the driveplotr validation drives (9, 10, 12, 13, 15)
of at least 100 points gets, at random places, transient faults (1-5 points),
one intermittent episode (3-6 bursts of 1-3 points, 3-15 normal points apart)
and, in every other segment, a permanent fault over its last 20-100 points;
each fault shifts east and north by a random 10-50 m offset. Scores: anomaly
F1 and normal F1 of the per-point flag (either channel), and the horizontal
RMSE over the faulty transient/intermittent points: corrupted, after the
paper's EMA recovery and after constant-velocity recovery.

Usage: ``python benchmarks/rema_quality.py [--json OUT]`` (needs ../shared/data).
"""

from __future__ import annotations

import os

os.environ.setdefault("NUMBA_NUM_THREADS", "1")

import argparse
import json
import sys
from pathlib import Path

import numpy as np
import pandas as pd

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO / "src"))

from gradgps import preprocess, to_fixes  # noqa: E402
from gradgps._core_pipeline import CoreParams, core_batch  # noqa: E402
from gradgps._recovery import RecoveryParams  # noqa: E402
from gradgps._rema import RemaParams  # noqa: E402
from gradgps._tuning import f1_scores  # noqa: E402

VALIDATION = (9, 10, 12, 13, 15)


def inject(n: int, rng: np.random.Generator, permanent: bool) -> tuple[np.ndarray, np.ndarray]:
    """Per point (offset east/north, label 0 none / 1 repairable / 2 permanent)."""
    off = np.zeros((n, 2))
    label = np.zeros(n, dtype=np.int8)

    def shift(a: int, b: int, kind: int) -> None:
        ang = rng.uniform(0, 2 * np.pi)
        off[a:b] = rng.uniform(10, 50) * np.array([np.cos(ang), np.sin(ang)])
        label[a:b] = kind

    end = n - int(rng.integers(20, 101)) if permanent else n
    if permanent:
        shift(end, n, 2)
    for _ in range(max(1, end // 150)):
        a = int(rng.integers(20, max(21, end - 10)))
        shift(a, min(end - 5, a + int(rng.integers(1, 6))), 1)
    a = int(rng.integers(20, max(21, end - 70)))
    for _ in range(int(rng.integers(3, 7))):
        b = min(a + int(rng.integers(1, 4)), end - 5)
        if b > a:
            shift(a, b, 1)
        a = b + int(rng.integers(3, 16))
    return off, label


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--data", type=Path, default=Path(os.environ.get("GRADGPS_DATA", "/work/shared/data")))
    ap.add_argument("--json", type=Path, default=None)
    args = ap.parse_args()
    raw = pd.read_csv(args.data / "driveplotr_nds.csv")
    raw = raw[raw["drive"].isin(VALIDATION)]
    fixes = to_fixes(raw.rename(columns={"speed_mps": "speed", "heading_deg": "heading"}))
    prep = preprocess(fixes)
    rng = np.random.default_rng(0)
    segments = []
    for k, (_, sl) in enumerate(prep.segment_slices()):
        pts = prep.points.iloc[sl]
        if len(pts) < 100:
            continue
        off, label = inject(len(pts), rng, permanent=k % 2 == 0)
        segments.append((pts, off, label))
    variants = {
        "paper (defaults)": RemaParams(),
        "paper, min_margin 3 m": RemaParams(min_margin=3.0),
        "trend, min_margin 3 m": RemaParams(mode="trend", min_margin=3.0),
        "trend, min_margin 5 m, sens 4": RemaParams(mode="trend", min_margin=5.0, sensitivity=4.0),
    }
    results: dict[str, dict[str, float]] = {}
    for name, rp in variants.items():
        flags, labels = [], []
        err: dict[str, list[np.ndarray]] = {"corrupted": [], "ema": [], "velocity": []}
        for pts, off, label in segments:
            e_true = pts["east"].to_numpy()
            n_true = pts["north"].to_numpy()
            e, n = e_true + off[:, 0], n_true + off[:, 1]
            rep = label == 1
            err["corrupted"].append(np.hypot(e - e_true, n - n_true)[rep])
            for method in ("ema", "velocity"):
                prm = CoreParams(period=1.0, rema=rp, recovery=RecoveryParams(method=method))
                out = core_batch(e, n, prm, speed=pts["speed"].to_numpy(),
                                 heading=pts["heading"].to_numpy())
                err[method].append(np.hypot(out.east_clean - e_true, out.north_clean - n_true)[rep])
            flags.append(out.flag)
            labels.append(label > 0)
        fa, fn = f1_scores(np.concatenate(flags), np.concatenate(labels))
        results[name] = {
            "f1_anomaly": round(fa, 3), "f1_normal": round(fn, 3),
            **{f"rmse_{k}_m": round(float(np.sqrt(np.mean(np.concatenate(v) ** 2))), 2)
               for k, v in err.items()},
        }
    results["_points"] = {"total": int(sum(len(s[0]) for s in segments)),
                          "anomalous": int(sum((s[2] > 0).sum() for s in segments))}
    text = json.dumps(results, indent=2)
    print(text)
    if args.json is not None:
        args.json.write_text(text + "\n")


if __name__ == "__main__":
    main()

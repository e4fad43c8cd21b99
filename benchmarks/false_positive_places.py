"""Where a model's false positives sit relative to the injected faults (validation splits).

For tuning and diagnosis, never the test splits. Protocol ``grad`` (seed 0) on
each real data set's validation split, positions only (t, lat, lon), at the
native rate or decimated (``--rate 0.5``). Every normal fix the detector flags
is put in one place: ``after K: BIAS`` (K = 1, 2, 3 fixes after the last
faulty fix, and the bias of that fault), ``after 4-10``, ``before`` (within 3
fixes before a fault starts), ``after 11-100`` or ``far`` (no fault within
100 fixes before). Run:

    python benchmarks/false_positive_places.py [--model DIR] [--rate native|0.5] [--data-dir DIR]
"""

from __future__ import annotations

import argparse
from collections import Counter

import numpy as np
from _validation_drives import validation_positions

from gradgps._data.inject import inject_grad
from gradgps._grad.detector import Detector
from gradgps._tracks.track import to_fixes

FAR = 10**9


def places(faulty: np.ndarray, bias: np.ndarray, flagged: np.ndarray) -> Counter[str]:
    """The place of every flagged normal fix (rows in file order, one track after another)."""
    n = len(faulty)
    since = np.full(n, FAR)
    last_bias = np.full(n, "", dtype=object)
    last, kind = -FAR, ""
    for i in range(n):
        if faulty[i]:
            last, kind = i, bias[i]
        since[i], last_bias[i] = i - last, kind
    until = np.full(n, FAR)
    upcoming = FAR
    for i in range(n - 1, -1, -1):
        if faulty[i]:
            upcoming = i
        until[i] = upcoming - i
    out: Counter[str] = Counter()
    for i in np.flatnonzero(flagged & ~faulty):
        if since[i] <= 3:
            out[f"after {since[i]}: {last_bias[i]}"] += 1
        elif since[i] <= 10:
            out["after 4-10"] += 1
        elif until[i] <= 3:
            out["before"] += 1
        elif since[i] <= 100:
            out["after 11-100"] += 1
        else:
            out["far"] += 1
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--model", default=None, help="model directory (default: shipped)")
    parser.add_argument("--rate", choices=("native", "0.5"), default="native")
    parser.add_argument("--data-dir", default=None)
    args = parser.parse_args()
    det = Detector(args.model)
    total: Counter[str] = Counter()
    print(f"rate {args.rate}: false positives by place")
    print("| data set | normal fixes | false positives | by place |")
    print("|---|---|---|---|")
    period = None if args.rate == "native" else 2.0
    for name, data, cols, cmap, _ in validation_positions(period, args.data_dir):
        labelled = inject_grad(data, seed=0, columns=cmap)
        faulty = labelled["label_anomaly"].to_numpy() == 1
        bias = labelled["label_bias"].to_numpy()
        flagged = det.detect(to_fixes(labelled[cols], cmap))["anomaly"].to_numpy() == 1
        found = places(faulty, bias, flagged)
        total += found
        text = ", ".join(f"{k} {v}" for k, v in sorted(found.items()))
        print(f"| {name} | {int((~faulty).sum()):,} | {sum(found.values())} | {text} |")
    text = ", ".join(f"{k} {v}" for k, v in sorted(total.items()))
    print(f"| all | | {sum(total.values())} | {text} |")


if __name__ == "__main__":
    main()

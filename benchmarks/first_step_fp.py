"""False-positive rate of a clean drive with one odd first time step (docs/reliability.md).

A segment's sampling period is the median of its first 5 time steps, so one
fix 0.1 s or 1.1 ms after the first must not change the verdicts of the rest
of the drive. Per seed (0..3): a 600-fix 1 Hz straight drive (about 7 m/s,
receiver noise of a few metres), as is and with one extra fix 0.1 s or
1.1 ms after the first; prints the share of fixes flagged by the default
model for each. Run:

    python benchmarks/first_step_fp.py
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from gradgps import Detector

N_FIXES = 600
SEEDS = range(4)
EXTRA_STEPS = {"none": None, "0.1 s": 0.1, "1.1 ms": 0.0011}


def main() -> None:
    det = Detector()
    rates: dict[str, list[float]] = {name: [] for name in EXTRA_STEPS}
    for seed in SEEDS:
        rng = np.random.default_rng(seed)
        t = 1.7e9 + np.arange(N_FIXES, dtype=float)
        lat = 48.1 + rng.normal(0, 1.5e-5, N_FIXES)
        lon = 11.5 + np.arange(N_FIXES) * 1e-4 + rng.normal(0, 2.2e-5, N_FIXES)
        drive = pd.DataFrame({"track": "a", "t": t, "lat": lat, "lon": lon})
        for name, extra in EXTRA_STEPS.items():
            table = drive
            if extra is not None:
                row = pd.DataFrame(
                    {"track": ["a"], "t": [t[0] + extra], "lat": [lat[0]], "lon": [lon[0]]}
                )
                table = pd.concat([drive.iloc[:1], row, drive.iloc[1:]], ignore_index=True)
            rates[name].append(float(det.detect(table)["anomaly"].mean()))
    for name, values in rates.items():
        per_seed = " ".join(f"{v:.3f}" for v in values)
        print(f"{name:>7}: per seed {per_seed}  mean {np.mean(values):.4f}")


if __name__ == "__main__":
    main()

"""A model on simulated drives from noisier receivers than the simulator's logger.

Most real files come from phones and cheap loggers, many in cities: their
position error is larger and changes faster than a good-sky logger's. A
receiver's noise is no fault. Per receiver (the simulator's logger, and three
noisier ones: a slowly varying error of ``sigma`` m per axis with time constant
``tau`` s, plus heavy-tailed epoch noise of ``white`` m) and rate (1, 0.5, 5 Hz):
the share of clean fixes flagged on six fresh 15-minute drives (simulator seed
4242, positions only), and protocol ``grad`` (seed 0) anomaly F1 and normal
recall on the same drives. Never a test split. Run with the sources to judge on
``PYTHONPATH``:

    python benchmarks/tried/receiver_noise_check.py [--model DIR]
"""

from __future__ import annotations

import argparse

import numpy as np
import pandas as pd

from gradgps._data.inject import inject_grad
from gradgps._data.simulator import SimulatorParams, simulate_fleet
from gradgps._grad.detector import Detector
from gradgps._result import f1_score
from gradgps._tracks.track import ColumnMap, to_fixes

POSITIONS = ColumnMap(track="track", time="t", lat="lat", lon="lon", speed="", heading="")
RECEIVERS = (
    ("logger (the simulator's)", {}),
    ("phone: 3 m over 60 s + 0.5 m", {"sigma": 3.0, "tau": 60.0, "white": 0.5}),
    ("city: 5 m over 20 s + 1.5 m", {"sigma": 5.0, "tau": 20.0, "white": 1.5}),
    ("poor: 8 m over 10 s + 3 m", {"sigma": 8.0, "tau": 10.0, "white": 3.0}),
)


def receiver_drives(noise: dict[str, float], hz: float) -> pd.DataFrame:
    """Six fresh 15-minute simulated drives (seed 4242; track, t, lat, lon) at ``hz`` from a
    receiver of :data:`RECEIVERS` (``{}``: the simulator's logger)."""
    params = SimulatorParams(
        **(
            {
                "gnss_correlated_sigma": noise["sigma"],
                "gnss_correlation_time": noise["tau"],
                "gnss_white_sigma": noise["white"],
            }
            if noise
            else {}
        )
    )
    sim = simulate_fleet(6, 15.0, hz, 4242, imu=False, params=params)
    return sim[["track", "t", "lat", "lon"]]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--model", default=None, help="model directory (default: shipped)")
    args = parser.parse_args()
    det = Detector(args.model)
    print("| receiver | rate | clean false alarms | anomaly F1 | normal recall |")
    print("|---|---|---|---|---|")
    for name, noise in RECEIVERS:
        for hz in (1.0, 0.5, 5.0):
            sim = receiver_drives(noise, hz)
            clean = det.detect(to_fixes(sim, POSITIONS))["anomaly"].to_numpy() == 1
            labelled = inject_grad(sim, seed=0, columns=POSITIONS)
            flagged = (
                det.detect(to_fixes(labelled[["track", "t", "lat", "lon"]], POSITIONS))[
                    "anomaly"
                ].to_numpy()
                == 1
            )
            truth = labelled["label_anomaly"].to_numpy() == 1
            print(
                f"| {name} | {hz:g} Hz | {100 * clean.mean():.2f} % | "
                f"{f1_score(truth, flagged):.3f} | {np.mean(~flagged[~truth]):.4f} |"
            )


if __name__ == "__main__":
    main()

"""How two ways of measuring a receiver's noise from its fixes separate noisy receivers
from quiet ones with faults, per rate: the input of the tried ``receiver_noise_m``.

A fix's *sample* is how far it lands from the line its two predecessors draw, over
that distance's spread for white noise (steps within a factor of two). ``--measure
mean`` (``receiver_noise_feature.patch``): the exponential of a running mean of the
samples' logarithms, time constant 60 s, each clipped to within 1.5 nats of it.
``--measure low`` (``receiver_noise_feature_v2.patch``): the same mean moving up with
a time constant of 300 s and down with 30 s (so it settles on a low quantile), plain
``1 / n`` averaging over the first samples, and triples where the receiver pinned (a
step under 5 cm) left out. Per set of drives: percentiles of the measure over the
fixes (each track's first minute left out): the real validation drives at their
native rate and at 0.5 Hz, and the simulated receivers of ``receiver_noise_check.py``
(six 15-minute drives, seed 4242) at 1, 0.5 and 5 Hz, the logger also with protocol
``grad`` faults (seed 0). Never a test split. Run from the repository root:

    python benchmarks/tried/receiver_noise_measure.py [--measure mean|low]
"""

from __future__ import annotations

import argparse
import math
import sys
from pathlib import Path

import numpy as np
import pandas as pd

from gradgps._data.inject import inject_grad

sys.path.insert(0, str(Path(__file__).resolve().parent))
sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # benchmarks/, for the helpers
from _validation_drives import validation_positions
from receiver_noise_check import POSITIONS, RECEIVERS, receiver_drives

_R_EARTH = 6_371_000.0


def measure(t: np.ndarray, east: np.ndarray, north: np.ndarray, how: str) -> np.ndarray:
    """Per fix, the receiver's noise as measured before it (m; 0 until measured)."""
    out = np.zeros(len(t))
    log_q: float | None = None
    samples = 0
    seen: list[tuple[float, float, float]] = []
    for i in range(len(t)):
        dt = float(t[i] - t[i - 1]) if i else 1.0
        out[i] = math.exp(log_q) if log_q is not None else 0.0
        if len(seen) == 2 and seen[1][2] > 0 and 0.5 <= dt / seen[1][2] <= 2.0:
            rho = dt / seen[1][2]
            (e2, n2, _), (e1, n1, _) = seen
            moved = min(math.hypot(east[i] - e1, north[i] - n1), math.hypot(e1 - e2, n1 - n2))
            if how == "mean" or moved >= 0.05:
                d2 = math.hypot(east[i] - e1 - (e1 - e2) * rho, north[i] - n1 - (n1 - n2) * rho)
                sample = math.log(max(d2 / math.sqrt(1 + (1 + rho) ** 2 + rho**2), 0.01))
                samples += 1
                if log_q is None:
                    log_q = sample
                else:
                    clipped = min(max(sample, log_q - 1.5), log_q + 1.5)
                    if how == "mean":
                        rate = 1 - math.exp(-dt / 60.0)
                    else:
                        tau = 300.0 if clipped > log_q else 30.0
                        rate = max(1 / samples, 1 - math.exp(-dt / tau))
                    log_q += rate * (clipped - log_q)
        seen = [*seen, (float(east[i]), float(north[i]), dt)][-2:]
    return out


def percentiles(table: pd.DataFrame, how: str) -> np.ndarray:
    values = []
    for _, g in table.groupby("track", sort=False):
        lat, lon = g["lat"].to_numpy(np.float64), g["lon"].to_numpy(np.float64)
        lat0 = float(np.mean(lat))
        east = np.radians(lon - np.mean(lon)) * _R_EARTH * math.cos(math.radians(lat0))
        north = np.radians(lat - lat0) * _R_EARTH
        t = g["t"].to_numpy(np.float64)
        m = measure(t, east, north, how)
        values.append(m[t - t[0] >= 60.0])
    v = np.concatenate(values)
    return np.percentile(v[v > 0], [10, 50, 90, 99])


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--measure", choices=("mean", "low"), default="low")
    args = parser.parse_args()
    print("| drives | p10 m | p50 m | p90 m | p99 m |")
    print("|---|---|---|---|---|")

    def row(name: str, table: pd.DataFrame) -> None:
        cells = " | ".join(f"{x:.2f}" for x in percentiles(table, args.measure))
        print(f"| {name} | {cells} |")

    for period in (None, 2.0):
        for name, data, _, cmap, _ in validation_positions(period, keep_native=True):
            canonical = data.rename(
                columns={cmap.track: "track", cmap.time: "t", cmap.lat: "lat", cmap.lon: "lon"}
            )
            row(f"{name} validation, {'native' if period is None else '0.5 Hz'}", canonical)
    for name, noise in RECEIVERS:
        for hz in (1.0, 0.5, 5.0):
            sim = receiver_drives(noise, hz)
            row(f"simulated {name}, {hz:g} Hz", sim)
            if not noise:
                row(
                    f"simulated {name}, {hz:g} Hz, grad faults",
                    inject_grad(sim, seed=0, columns=POSITIONS),
                )


if __name__ == "__main__":
    main()

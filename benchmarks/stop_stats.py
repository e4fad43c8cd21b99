"""How cars stop, as the fixes show it: the real train/validation drives against the simulator.

The evidence behind the simulator's stop settings (``static_hold_speed_max``,
``hard_stop_*``, ``long_stop_*`` in ``src/gradgps/_data/simulator.py``, table in
``docs/simulator.md``): a detector that never saw a hard halt onto a pinned fix
reads one as a frozen receiver. Per set of drives, thinned to at most 1 Hz
(native for 0.5 Hz), tracks split where a real glitch was (as the training recipe
does): the share of standing steps (slower than 1 m/s) whose fix repeats the last
one exactly; and per *stop* (a run of standing steps lasting 3 s or more that holds
a repeated fix) its length, the speed of the step into it (``v_last``), the hardest
fix-derived braking in the 5 s before (``a_max5``), and whether its first moving
step is a catch-up (2 m/s faster than the step after). ``real``: the train and
validation splits of Austin 2006, Nevada, NL motorway, DrivePlotR (never test);
``sim``: the simulated drives the training recipe draws (each rate, train and
validation seeds). Run:

    python benchmarks/stop_stats.py real
    python benchmarks/stop_stats.py sim
"""

from __future__ import annotations

import sys

import numpy as np
import pandas as pd

from gradgps._data.datasets import load_dataset
from gradgps._data.simulator import simulate_fleet
from gradgps._tracks.geo import LocalFrame
from gradgps._train.recipe import DefaultRecipe, _canonical, decimate_tracks

STILL = 1.0  # m/s: a step slower than this is standing (DrivePlotR jitters by ~0.6 m)
HARD = 4.0  # m/s²: braking above this is a hard stop
CATCH_UP = 2.0  # m/s: a first moving step this much faster than the next is a catch-up


def stops_of(table: pd.DataFrame) -> tuple[list[dict[str, float]], dict[str, float]]:
    """Every stop of ``table`` (see the module docstring) and totals over its steps."""
    out: list[dict[str, float]] = []
    n_steps = n_still = n_still_rep = n_rep = 0
    for _, g in table.groupby("track", sort=False):
        t = g["t"].to_numpy(float)
        lat = g["lat"].to_numpy(float)
        lon = g["lon"].to_numpy(float)
        if t.size < 10:
            continue
        e, n = LocalFrame(lat[0], lon[0]).to_local(lat, lon)
        dt = np.diff(t)
        ok = dt <= 3 * float(np.median(dt)) + 1e-6  # no logging gap
        v = np.hypot(np.diff(e), np.diff(n)) / np.maximum(dt, 1e-9)
        rep = (lat[1:] == lat[:-1]) & (lon[1:] == lon[:-1])
        still = ok & (v < STILL)
        n_steps += int(ok.sum())
        n_still += int(still.sum())
        n_still_rep += int((still & rep).sum())
        n_rep += int((ok & rep).sum())
        # a logging gap over an exactly repeated fix is standing time too (Austin skips rows)
        standing = (v < STILL) & (ok | rep)
        i, m = 0, standing.size
        while i < m:
            if not standing[i]:
                i += 1
                continue
            a = b = i
            while b + 1 < m and standing[b + 1]:
                b += 1
            i = b + 1
            length = float(t[b + 1] - t[a])
            if length < 3.0 or not rep[a : b + 1].any():
                continue
            first_rep = a + int(np.argmax(rep[a : b + 1]))
            stop: dict[str, float] = {
                "length": length,
                "repeated": float(rep[a : b + 1].mean()),
                "to_first_repeat": float(t[first_rep] - t[a]),
            }
            if a >= 1 and ok[a - 1]:
                stop["v_last"] = float(v[a - 1])
                braking = [(v[a - 1] - v[a]) / (0.5 * (dt[a - 1] + dt[a]))]
                s = a - 1
                while s >= 1 and t[a] - t[s] <= 5.0 + 1e-6 and ok[s - 1]:
                    braking.append((v[s - 1] - v[s]) / (0.5 * (dt[s - 1] + dt[s])))
                    s -= 1
                stop["a_max5"] = float(max(braking))
            if b + 2 < m and ok[b + 1] and ok[b + 2]:
                stop["catch_up"] = float(v[b + 1] > v[b + 2] + CATCH_UP)
            out.append(stop)
    totals = {
        "steps": n_steps,
        "repeated_of_standing": n_still_rep / max(n_still, 1),
        "repeated": n_rep / max(n_steps, 1),
    }
    return out, totals


def _spread(values: list[float]) -> str:
    if not values:
        return "-"
    a = np.asarray(values)
    return "/".join(f"{q:.1f}" for q in np.percentile(a, [10, 50, 90])) + f", max {a.max():.1f}"


def _share(flags: list[bool]) -> str:
    return f"{np.mean(flags):.0%}" if flags else "-"


def row(name: str, table: pd.DataFrame) -> str:
    """One table row for ``table`` (thinned to at most 1 Hz first)."""
    period = table.groupby("track", sort=False)["t"].diff().median()
    stops, totals = stops_of(decimate_tracks(table, 1.0) if period < 0.9 else table)

    def column(key: str) -> list[float]:
        return [s[key] for s in stops if key in s]

    return (
        f"| {name} | {totals['repeated_of_standing']:.0%} | {len(stops)} | "
        f"{_spread(column('length'))} | {_spread(column('v_last'))} | "
        f"{_share([a > HARD for a in column('a_max5')])} | "
        f"{_share([c == 1.0 for c in column('catch_up')])} |"
    )


def main() -> None:
    what = sys.argv[1] if len(sys.argv) > 1 else "real"
    print(
        "| drives | standing steps with the fix repeated | stops | length s p10/50/90 | "
        "v_last m/s p10/50/90 | braking > 4 m/s² | catch-up exits |"
    )
    print("|---|---|---|---|---|---|---|")
    if what == "real":
        for name in ("austin2006", "nevada", "nl_motorway", "driveplotr"):
            for split in ("train", "validation"):
                print(row(f"{name} {split}", _canonical(load_dataset(name, split), "")))
    elif what == "sim":
        recipe = DefaultRecipe()
        rates = zip(recipe.sim_rates_hz, recipe.sim_tracks, strict=True)
        for k, (rate, count) in enumerate(rates):
            for split in ("train", "validation"):
                n = count if split == "train" else max(2, count // 4)
                seed = 30_000 + 100 * recipe.seed + 10 * k + (0 if split == "train" else 1)
                drives = simulate_fleet(n, recipe.sim_minutes, rate, seed, imu=False)
                print(row(f"simulated {rate:g} Hz {split}", _canonical(drives, "")))
    else:
        raise SystemExit("give real or sim")


if __name__ == "__main__":
    main()

"""The offset tracker with a fourth mode, *drift*, in its readable form only: an experiment
for issues 13 and 16, not the product.

Why: a receiver that is pulled off the track slowly and then snaps back (a multipath
pull-off, a logger lagging through a curve) leaves the tracker's three modes one
reading: the pulled-off fixes look like driving, so the track follows them, and the
snap-back onto the real track looks like a jump starting, which the network then flags
on the fixes that are right (``benchmarks/receiver_consensus.py``: the NL USB logger
three fixes 9-16 m off, the five after them flagged). A drift mode says what a
careful engineer would: the fix is ``z = p + o + e`` where the offset ``o`` grows
at a rate ``w`` (``o' = w``, ``w`` a slow random walk); a drift starts from the clean
track (``o = 0``, ``w`` unknown, spread ``drift_w0`` m/s) at ``drift_per_s`` and ends
(snaps back: ``o -> 0``) with the same hazard as a jump. Then at a snap-back the
hypothesis "the last fixes drifted, this one is clean on a track that went on
smoothly" competes with "this is a jump", and the revised previous offset says the
fixes before were the fault.

This module copies :func:`gradgps._grad.offset._reference_channel` and adds the mode
(every hypothesis carries ``o`` and ``w`` in a five-state Kalman filter; outside a
drift they are 0 and certain); with ``drift_per_s = 0`` it gives the shipped
reference's output (a test checks it). What it measures, tracker alone (no network):
the best hypothesis's offset on the NL motorway validation drives (clean and with
protocol ``grad`` faults, positions only), the share of normal fixes with a phantom
above ``PHANTOM_M`` and on the USB logger's snap-back. Run:

    python benchmarks/tried/drift_mode_reference.py [--drift-per-s 0.005] [--drift-w0 2]
        [--drift-track-q 1] [--synthetic | --dataset nl_motorway [--inject-seed 0]
        [--rows FIRST:LAST]]
"""

from __future__ import annotations

import argparse
import math
from dataclasses import dataclass

import numpy as np

from gradgps._data.datasets import load_dataset
from gradgps._data.inject import inject_grad
from gradgps._grad import offset as om
from gradgps._tracks.track import to_fixes

DRIFT = 3.0
PHANTOM_M = 8.0
_EARTH_M_PER_DEG = 111_320.0


@dataclass
class DriftSettings:
    """``drift_per_s``: how often a drift starts on a clean track (0: no drift mode);
    ``drift_w0``: m/s, the spread of its rate where it starts; ``drift_wdot``: m/s²,
    how fast the rate itself wanders; ``drift_track_q``: the clean track's process
    noise during a drift, as a share of Singer's (below 1: the hypothesis that the
    fixes, not the car, moved off)."""

    drift_per_s: float = 0.005
    drift_w0: float = 2.0
    drift_wdot: float = 0.05
    drift_track_q: float = 1.0


_H = om._Hypothesis  # its track state here has five entries: + drift offset, drift rate


def reported(h: _H) -> float:
    """The offset hypothesis ``h`` reports (0 when clean; a drift's is its state's)."""
    if h.mode == om.CLEAN:
        return 0.0
    return float(h.x[3]) if h.mode == DRIFT else h.offset


_H_TRACK = np.array([1.0, 0.0, 0.0, 0.0, 0.0])
_H_DRIFT = np.array([1.0, 0.0, 0.0, 1.0, 0.0])


def _matrices(p: np.ndarray, dt: float, ds: DriftSettings) -> tuple[np.ndarray, np.ndarray]:
    f3, q3 = om._singer_matrices(p, dt)
    f, q = np.eye(5), np.zeros((5, 5))
    f[:3, :3], q[:3, :3] = f3, q3
    f[3, 4] = dt
    w2 = ds.drift_wdot**2
    q[3:, 3:] = w2 * np.array([[dt**3 / 3, dt**2 / 2], [dt**2 / 2, dt]])
    return f, q


def _clear_drift(h: _H) -> None:
    """Leave a drift: its offset and rate 0 and certain (the track keeps what it knows)."""
    h.x[3:] = 0.0
    h.cov[3:, :] = 0.0
    h.cov[:, 3:] = 0.0


def drift_channel(
    prm: om.OffsetParams, ds: DriftSettings, dt: np.ndarray, z: np.ndarray, repeated: np.ndarray
) -> np.ndarray:
    """Per fix: the best hypothesis's offset, its mode, and the previous fix's offset as
    the best hypothesis's history has it now (positions only)."""
    p = prm.to_array()
    r = prm.sigma_m**2
    log_u = -math.log(2 * prm.span_m)
    out = np.zeros((len(z), 3))
    beam: list[_H] = []
    since_start = 0.0
    for i in range(len(z)):
        if i == 0 or not dt[i] > 0:
            cov = np.zeros((5, 5))
            cov[:3, :3] = np.diag([r, prm.v0_sigma**2, prm.sigma_a**2])
            beam = [_H(np.array([z[i], 0.0, 0.0, 0.0, 0.0]), cov, 0.0, 0.0, 0.0, om.CLEAN)]
            since_start = 0.0
            continue
        d = float(dt[i])
        since_start += d
        live = math.log(1 - om._HELD) if repeated[i] else 0.0
        log_restart = om._log_restart(p, since_start, d)
        f, q = _matrices(p, d, ds)
        q_drift = q.copy()
        q_drift[:3, :3] *= ds.drift_track_q
        drift_start = 1.0 - math.exp(-ds.drift_per_s * d) if ds.drift_per_s > 0 else 0.0
        kids: list[_H] = []
        restart = None
        for j, parent in enumerate(beam):
            h = parent.copy()
            h.x = f @ h.x
            h.cov = f @ h.cov @ f.T + (q_drift if h.mode == DRIFT else q)
            if h.mode != DRIFT:
                _clear_drift(h)
            h.previous = reported(h)
            if j == 0:
                restart = h.copy()
                restart.x = np.array([z[i], h.x[1], 0.0, 0.0, 0.0])
                restart.offset, restart.age, restart.mode = 0.0, 0.0, om.CLEAN
                restart.cov = np.zeros((5, 5))
                restart.cov[:3, :3] = np.diag(
                    [r, max(h.cov[1, 1], prm.v0_sigma**2), prm.sigma_a**2]
                )
                restart.weight += live + log_restart + log_u
            mode = om.JUMP if h.mode == DRIFT else h.mode  # a drift ends, switches as a jump
            to_clean, to_keep, to_jump, to_noise = om._transitions(p, mode, d)
            if h.mode == om.CLEAN and drift_start > 0:
                to_clean = math.log(max(math.exp(to_clean) - drift_start, om._TINY))
            age = h.age + d if h.mode != om.CLEAN else d
            clean = h.copy()
            _clear_drift(clean)
            clean.weight += live + to_clean + clean.measure(float(z[i]), r, row=_H_TRACK)
            clean.offset, clean.age, clean.mode = 0.0, 0.0, om.CLEAN
            kids.append(clean)
            if h.mode == om.JUMP:
                keep = h.copy()
                keep.weight += (
                    live + to_keep + keep.measure(float(z[i]) - h.offset, r, row=_H_TRACK)
                )
                keep.age = age
                kids.append(keep)
            if h.mode == DRIFT:
                keep = h.copy()
                keep.weight += live + to_keep + keep.measure(float(z[i]), r, row=_H_DRIFT)
                keep.age = age
                kids.append(keep)
            if h.mode == om.CLEAN and drift_start > 0:
                drift = h.copy()
                drift.cov[4, 4] = ds.drift_w0**2  # the rate unknown, the offset 0 so far
                drift.x[3] = drift.x[4] = 0.0
                drift.mode, drift.age = DRIFT, d
                drift.weight += live + math.log(drift_start)
                drift.weight += drift.measure(float(z[i]), r, row=_H_DRIFT)
                kids.append(drift)
            for m, log_p in ((om.JUMP, to_jump), (om.NOISE, to_noise)):
                fault = h.copy()
                _clear_drift(fault)
                fault.offset, fault.age, fault.mode = float(z[i]) - float(h.x[0]), age, m
                held = m == om.NOISE and repeated[i]
                fault.weight += (math.log(om._HELD) if held else live + log_p) + log_u
                kids.append(fault)
        assert restart is not None
        kids.append(restart)
        free = om.BEAM - om._RESERVED - (1 if ds.drift_per_s > 0 else 0)
        beam = kept = om.best_of(kids, free, reported)
        out[i] = (reported(kept[0]), kept[0].mode, kept[0].previous)
    return out


def tracker_offsets(
    east: np.ndarray, north: np.ndarray, t: np.ndarray, ds: DriftSettings
) -> np.ndarray:
    """``(n, 4)``: offset norm, best mode east, best mode north, previous offset norm."""
    prm = om.OffsetParams()
    dt = np.r_[0.0, np.diff(t)]
    repeated = np.r_[False, (np.diff(east) == 0) & (np.diff(north) == 0)]
    e = drift_channel(prm, ds, dt, east, repeated)
    n = drift_channel(prm, ds, dt, north, repeated)
    return np.c_[np.hypot(e[:, 0], n[:, 0]), e[:, 1], n[:, 1], np.hypot(e[:, 2], n[:, 2])]


def synthetic_pull_off(seed: int = 1) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """A straight 25 m/s drive at 1 Hz, 2 m receiver noise, whose fixes 60-65 are pulled
    off sideways at 3 m/s (18 m at the last) and snap back at fix 66: ``(t, east, north)``."""
    rng = np.random.default_rng(seed)
    t = np.arange(120.0)
    east = 25.0 * t + rng.normal(0, 2, t.size)
    north = rng.normal(0, 2, t.size)
    north[60:66] += 3.0 * np.arange(1, 7)
    return t, east, north


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--dataset", default="nl_motorway")
    parser.add_argument("--drift-per-s", type=float, default=0.005)
    parser.add_argument("--drift-w0", type=float, default=2.0)
    parser.add_argument("--drift-track-q", type=float, default=1.0)
    parser.add_argument("--inject-seed", type=int, default=None)
    parser.add_argument("--rows", default=None, help="FIRST:LAST, print these rows")
    parser.add_argument(
        "--synthetic", action="store_true", help="the pull-off of synthetic_pull_off"
    )
    parser.add_argument("--data-dir", default=None)
    args = parser.parse_args()
    ds = DriftSettings(args.drift_per_s, args.drift_w0, drift_track_q=args.drift_track_q)
    if args.synthetic:
        t, e, n = synthetic_pull_off()
        res = tracker_offsets(e, n, t, ds)
        print(f"synthetic pull-off (fixes 60-65), {ds}: fix: offset norm m / best mode north")
        print(" ".join(f"{i}:{res[i, 0]:.0f}/{int(res[i, 2])}" for i in range(56, 76)))
        return
    table = load_dataset(args.dataset, "validation", data_dir=args.data_dir)
    table = table[["track", "t", "lat", "lon"]].reset_index(drop=True)
    cmap = to_fixes(table).attrs["columns"]
    truth = np.zeros(len(table), bool)
    if args.inject_seed is not None:
        labelled = inject_grad(table, seed=args.inject_seed, columns=cmap)
        truth = labelled["label_anomaly"].to_numpy() == 1
        table = labelled[["track", "t", "lat", "lon"]]
    lat0, lon0 = float(table["lat"].mean()), float(table["lon"].mean())
    east = ((table["lon"] - lon0) * _EARTH_M_PER_DEG * np.cos(np.radians(lat0))).to_numpy()
    north = ((table["lat"] - lat0) * _EARTH_M_PER_DEG).to_numpy()
    t = table["t"].to_numpy(np.float64)
    track = table["track"].astype(str).to_numpy()
    res = np.zeros((len(table), 4))
    for name in dict.fromkeys(track):
        rows = np.flatnonzero(track == name)
        tt = t[rows]
        gap = np.r_[True, np.diff(tt) > 10.0]  # a segment per gap, as the pipeline cuts
        seg = np.cumsum(gap)
        for s in np.unique(seg):
            sel = rows[seg == s]
            res[sel] = tracker_offsets(east[sel], north[sel], t[sel], ds)
    normal = ~truth
    phantom = normal & (res[:, 0] > PHANTOM_M)
    drift_best = (res[:, 1] == DRIFT) | (res[:, 2] == DRIFT)
    print(
        f"{args.dataset} validation, inject seed {args.inject_seed}, drift_per_s "
        f"{ds.drift_per_s:g}, drift_w0 {ds.drift_w0:g}, drift_track_q {ds.drift_track_q:g}: normal fixes {normal.sum():,}, "
        f"phantom > {PHANTOM_M:g} m {100 * phantom.mean() / max(normal.mean(), 1e-12):.2f} %, "
        f"best hypothesis a drift on {100 * (drift_best & normal).sum() / normal.sum():.2f} % "
        f"of them; faulty fixes with an offset > {PHANTOM_M:g} m "
        f"{(truth & (res[:, 0] > PHANTOM_M)).sum()} of {truth.sum()}"
    )
    if args.rows:
        first, last = (int(v) for v in args.rows.split(":"))
        print("row track t offset_norm mode_east mode_north previous_norm")
        for i in range(first, last):
            print(
                i,
                track[i],
                f"{t[i]:.1f}",
                f"{res[i, 0]:.1f}",
                int(res[i, 1]),
                int(res[i, 2]),
                f"{res[i, 3]:.1f}",
            )


if __name__ == "__main__":
    main()

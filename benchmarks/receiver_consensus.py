"""Real receiver faults without labels: each NL motorway receiver against the others in the same car.

Why: the clean drives carry no fault labels, yet some of their fixes are wrong
(``../shared/data/README.md``). The Dutch motorway trips were recorded by four
receivers riding in one car (two phones, a USB logger, a GoPro) on one
synchronised clock, so where three of them agree and the fourth does not, the
fourth is wrong, whatever the detector thinks. No injection protocol and no
detector choice enters the reference: it is the data's own witness (issues 13
and 16).

For every fix of every receiver: each *other* receiver's position at the fix's
time, interpolated linearly between its two fixes around it (the same segment,
at most ``MAX_BRACKET_S`` apart); the consensus is their component-wise median,
kept only where at least two of them lie within ``AGREE_M`` of it (two others
that disagree say nothing). The fix's *deviation* is its distance to the
consensus. Antennas a metre or two apart, clocks synchronised by the source,
and 1 Hz chords in motorway curves put honest deviations within a few metres;
``FAR_M`` is far beyond that. The shipped detector (or ``--model``) then reads
each receiver's track, positions only, as a user's file, and its verdicts are
cross-tabulated against the deviation: fixes far from the consensus it flags
(real faults found) and fixes near it it flags (false alarms the consensus
does not explain).

Never the test split unless asked once (``--split test``). Run:

    python benchmarks/receiver_consensus.py [--split validation|train|test] [--model DIR]
        [--runs] [--data-dir DIR]
"""

from __future__ import annotations

import argparse
import warnings
from typing import NamedTuple

import numpy as np
import pandas as pd

from gradgps._data.datasets import load_dataset
from gradgps._grad.detector import Detector
from gradgps._tracks.track import to_fixes

MAX_BRACKET_S = 2.5  # a gap longer than this says nothing of where that receiver was
AGREE_M = 10.0  # others further apart than this from their median are no consensus
NEAR_M = 5.0  # a fix this close to the consensus is where the car was
FAR_M = 20.0  # a fix this far from it is wrong
_EARTH_M_PER_DEG = 111_320.0


class Receiver(NamedTuple):
    """One receiver's fixes in one trip, in time order: segment names, t, east, north."""

    name: str
    segment: np.ndarray
    t: np.ndarray
    east: np.ndarray
    north: np.ndarray


def receiver_name(track: str) -> str:
    """``trip02_phone_samsung_s9_01`` -> ``trip02_phone_samsung_s9`` (segments share it)."""
    return track.rsplit("_", 1)[0]


def interpolate_at(rx: Receiver, t: np.ndarray) -> np.ndarray:
    """``(len(t), 2)`` east/north of ``rx`` at times ``t``, NaN where no two fixes of one
    segment at most :data:`MAX_BRACKET_S` apart hold ``t`` between them."""
    out = np.full((len(t), 2), np.nan)
    after = np.searchsorted(rx.t, t, side="left")
    exact = (after < len(rx.t)) & (rx.t[np.minimum(after, len(rx.t) - 1)] == t)
    out[exact] = np.c_[rx.east, rx.north][after[exact]]
    j = after - 1  # the fix at or before t; after = j + 1 the one after it
    ok = ~exact & (j >= 0) & (after < len(rx.t))
    jj, kk = j[ok], after[ok]
    ok_idx = np.flatnonzero(ok)
    same = (rx.segment[jj] == rx.segment[kk]) & (rx.t[kk] - rx.t[jj] <= MAX_BRACKET_S)
    jj, kk, ok_idx = jj[same], kk[same], ok_idx[same]
    w = (t[ok_idx] - rx.t[jj]) / (rx.t[kk] - rx.t[jj])
    out[ok_idx, 0] = rx.east[jj] + w * (rx.east[kk] - rx.east[jj])
    out[ok_idx, 1] = rx.north[jj] + w * (rx.north[kk] - rx.north[jj])
    return out


def consensus(others: list[np.ndarray]) -> np.ndarray:
    """Component-wise median of the others' ``(n, 2)`` positions, NaN where fewer than
    two of them lie within :data:`AGREE_M` of it."""
    stack = np.stack(others)  # (k, n, 2)
    with warnings.catch_warnings():  # an all-NaN slice: no consensus there, as returned
        warnings.simplefilter("ignore", RuntimeWarning)
        med = np.nanmedian(stack, axis=0)
    near = np.hypot(stack[..., 0] - med[None, :, 0], stack[..., 1] - med[None, :, 1]) <= AGREE_M
    med[near.sum(axis=0) < 2] = np.nan
    return med


def runs_of(mask: np.ndarray, group: np.ndarray) -> list[tuple[int, int]]:
    """``(first index, length)`` of every run of consecutive ``mask`` rows of one ``group``
    (a segment, a track): a run ends at a False row and where the group changes."""
    runs: list[tuple[int, int]] = []
    for i in np.flatnonzero(mask):
        if runs and runs[-1][0] + runs[-1][1] == i and group[i] == group[i - 1]:
            runs[-1] = (runs[-1][0], runs[-1][1] + 1)
        else:
            runs.append((int(i), 1))
    return runs


def trips(split: str, data_dir: str | None) -> dict[str, pd.DataFrame]:
    """Every trip of the split: the NL motorway receivers and the GoPro, t/lat/lon only."""
    tables = [
        load_dataset(name, split, data_dir=data_dir)[["track", "t", "lat", "lon"]]
        for name in ("nl_motorway", "nl_motorway_gopro")
    ]
    both = pd.concat(tables, ignore_index=True)
    trip = both["track"].astype(str).str.split("_").str[0]
    return {str(k): g.reset_index(drop=True) for k, g in both.groupby(trip, sort=True)}


def receivers_of(table: pd.DataFrame) -> list[Receiver]:
    """The trip's receivers in local metres (one tangent plane for the whole trip)."""
    lat0, lon0 = float(table["lat"].mean()), float(table["lon"].mean())
    out = []
    names = table["track"].astype(str).map(receiver_name)
    for name, g in table.groupby(names, sort=True):
        g = g.sort_values("t", kind="stable")
        out.append(
            Receiver(
                str(name),
                g["track"].astype(str).to_numpy(),
                g["t"].to_numpy(np.float64),
                ((g["lon"] - lon0) * _EARTH_M_PER_DEG * np.cos(np.radians(lat0))).to_numpy(),
                ((g["lat"] - lat0) * _EARTH_M_PER_DEG).to_numpy(),
            )
        )
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--split", default="validation", choices=("train", "validation", "test"))
    parser.add_argument("--model", default=None, help="model directory (default: shipped)")
    parser.add_argument("--runs", action="store_true", help="list every run beyond FAR_M")
    parser.add_argument(
        "--flagged", action="store_true", help="list every flagged fix and its deviation"
    )
    parser.add_argument("--data-dir", default=None)
    args = parser.parse_args()
    det = Detector(args.model)
    print(
        f"NL motorway, {args.split} split, model {args.model or 'shipped'}, positions only; "
        f"near <= {NEAR_M:g} m, far > {FAR_M:g} m from the other receivers' consensus"
    )
    head = (
        "| receiver | fixes | with a consensus | median deviation m | 99th percentile m "
        "| far (runs) | far flagged | near | near flagged | between flagged |"
    )
    print(head)
    print("|---" * (head.count("|") - 1) + "|")
    listed: list[str] = []
    flagged: list[str] = []
    for table in trips(args.split, args.data_dir).values():
        rxs = receivers_of(table)
        for rx in rxs:
            others = [interpolate_at(o, rx.t) for o in rxs if o.name != rx.name]
            if len(others) < 2:
                continue
            ref = consensus(others)
            dev = np.hypot(rx.east - ref[:, 0], rx.north - ref[:, 1])
            has = np.isfinite(dev)
            fixes = table[table["track"].astype(str).map(receiver_name) == rx.name]
            fixes = fixes.sort_values("t", kind="stable")
            flag = det.detect(to_fixes(fixes))["anomaly"].to_numpy() == 1
            far, near = has & (dev > FAR_M), has & (dev <= NEAR_M)
            between = has & ~far & ~near
            runs = runs_of(far, rx.segment)
            for i in np.flatnonzero(flag) if args.flagged else ():
                before = ", ".join(f"{d:.0f}" for d in dev[max(i - 3, 0) : i])
                flagged.append(
                    f"  {rx.segment[i]} t {rx.t[i]:.1f}: deviation {dev[i]:.1f} m"
                    f" (the three fixes before: {before} m)"
                )
            print(
                f"| {rx.name} | {len(dev):,} | {has.sum():,} | {np.median(dev[has]):.1f} "
                f"| {np.percentile(dev[has], 99):.1f} | {far.sum()} ({len(runs)}) "
                f"| {(flag & far).sum()} | {near.sum():,} | {(flag & near).sum()} "
                f"| {(flag & between).sum()} of {between.sum()} |"
            )
            for first, length in runs:
                sl = slice(first, first + length)
                listed.append(
                    f"  {rx.segment[first]} t {rx.t[first]:.1f}: {length} fixes, deviation up to "
                    f"{dev[sl].max():.0f} m, flagged {flag[sl].sum()} of {length}"
                    f" (the fix after: {'flagged' if first + length < len(flag) and flag[first + length] else 'not flagged'})"
                )
    if args.flagged:
        print("\nflagged fixes, their distance to the consensus:")
        print("\n".join(flagged) if flagged else "  none")
    if args.runs:
        print(f"\nruns of fixes more than {FAR_M:g} m from the consensus:")
        print("\n".join(listed) if listed else "  none")


if __name__ == "__main__":
    main()

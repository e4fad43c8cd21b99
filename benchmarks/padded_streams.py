"""Receivers' fixes re-sampled onto a faster clock: what the detector does, what the checks say.

A data logger or vehicle bus that samples a 1 Hz receiver's last fix at 5-10 Hz
writes each fix followed by exact copies of itself ("repeat"); some tools fill
the rows between fixes by straight lines instead ("interp"). Neither is in the
training data. For every real validation drive (positions only, native rate;
TUC, already at 4-5 Hz, left out) and each factor k: each fix's step is cut into
k rows, and the table says

* the share of rows the shipped model flags on the padded drive;
* the same when only the rows where the position changes are detected and each
  copy takes the verdict of the fix it repeats (what the ``repeated fixes``
  warning advises; for "interp" every row changes, so the two are the same);
* the warnings of :class:`gradgps._tracks.input_checks.InputChecks` (kinds).

No fault is injected: every flag is a false alarm (the native column is the drive
as recorded). Never the test splits. Run:

    python benchmarks/padded_streams.py [--model DIR] [--data-dir DIR] [--factors 2,5,10]
"""

from __future__ import annotations

import argparse
import warnings

import numpy as np
import pandas as pd
from _validation_drives import validation_positions

from gradgps._grad.detector import Detector
from gradgps._tracks.input_checks import InputChecks
from gradgps._tracks.track import to_fixes


def padded(table: pd.DataFrame, k: int, how: str) -> pd.DataFrame:
    """``table`` (track, t, lat, lon) with each step cut into ``k`` rows: the fix repeated
    (``how`` "repeat") or the straight line between the fixes ("interp")."""
    parts = []
    for track, g in table.groupby("track", sort=False):
        t, lat, lon = (g[c].to_numpy(dtype=np.float64) for c in ("t", "lat", "lon"))
        frac = np.arange(k) / k
        tt = np.r_[(t[:-1, None] + np.diff(t)[:, None] * frac).ravel(), t[-1:]]
        if how == "repeat":
            i = np.r_[np.repeat(np.arange(len(t) - 1), k), len(t) - 1]
            la, lo = lat[i], lon[i]
        else:
            la, lo = np.interp(tt, t, lat), np.interp(tt, t, lon)
        parts.append(pd.DataFrame({"track": track, "t": tt, "lat": la, "lon": lo}))
    return pd.concat(parts, ignore_index=True)


def flagged_updates_only(det: Detector, table: pd.DataFrame) -> np.ndarray:
    """Flags per row when only the rows whose position differs from the row before (and
    each track's first row) are detected, each other row taking its update's verdict."""
    same = (
        (table["track"] == table["track"].shift())
        & (table["lat"] == table["lat"].shift())
        & (table["lon"] == table["lon"].shift())
    ).to_numpy()
    keep = np.flatnonzero(~same)
    res = det.detect(table.iloc[keep].reset_index(drop=True))
    source = np.maximum.accumulate(np.where(~same, np.arange(len(table)), 0))
    verdict = np.zeros(len(table), np.int64)
    verdict[keep] = res["anomaly"].to_numpy(dtype=np.int64)
    return verdict[source]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--model", default=None)
    parser.add_argument("--data-dir", default=None)
    parser.add_argument("--factors", default="2,5,10")
    args = parser.parse_args()
    factors = [int(f) for f in args.factors.split(",")]
    det = Detector(args.model) if args.model else Detector()
    print(
        "| drive | rows | native | k | repeat | repeat, updates only | repeat: warnings |"
        " interp | interp: warnings |"
    )
    print("|---|---|---|---|---|---|---|---|---|")
    for name, table, cols, cmap, _ in validation_positions(None, args.data_dir, keep_native=True):
        if name == "tuc":
            continue
        base = table[cols].rename(columns={cmap.track: "track"}).astype({"t": np.float64})
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            native = det.detect(base)["anomaly"].mean()
            for k in factors:
                cells = []
                for how in ("repeat", "interp"):
                    up = padded(base, k, how)
                    share = det.detect(up)["anomaly"].mean()
                    kinds = [kind for kind, _ in InputChecks().add(to_fixes(up)).findings()]
                    cells.append((share, kinds))
                    if how == "repeat":
                        only = flagged_updates_only(det, up).mean()
                (rep, rep_kinds), (itp, itp_kinds) = cells
                print(
                    f"| {name} | {len(base):,} | {100 * native:.2f} % | {k} | {100 * rep:.2f} % | "
                    f"{100 * only:.2f} % | {', '.join(rep_kinds) or '-'} | {100 * itp:.2f} % | "
                    f"{', '.join(itp_kinds) or '-'} |",
                    flush=True,
                )


if __name__ == "__main__":
    main()

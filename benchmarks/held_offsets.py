"""Where the offset tracker holds an offset, by what the fix really is (validation splits).

For tuning the offset tracker, never the test splits. Protocol ``grad``
(seed 0) on each real data set's validation split, positions only (t, lat,
lon), at the native rate and decimated to 0.5 Hz (Nevada, natively 0.5 Hz,
counts in both). Over all of them, the share
of points whose offset norm exceeds 8 m (``PHANTOM_M``): on normal points (a
*phantom*: the hang-over issue 13 asks to remove), on jump-fault points (what
the tracker is for: should stay high) and on noise-fault points. Each
``--set`` runs the tracker with those ``OffsetParams`` fields changed (for
example ``--set sigma_m=3 --set sigma_m=5``); without one, the
defaults. Run:

    python benchmarks/held_offsets.py [--set FIELD=VALUE[,FIELD=VALUE...]] ... [--data-dir DIR]
"""

from __future__ import annotations

import argparse
import dataclasses

import numpy as np
from _validation_drives import validation_positions

from gradgps._data.inject import inject_grad
from gradgps._grad.defaults import MIN_STEP_S, grad_points
from gradgps._grad.pipeline import PipelineParams, grad_features, pipeline_feature_names
from gradgps._tracks.preprocess import stream_reasons
from gradgps._tracks.track import to_fixes

KINDS = ("none", "jump", "noise")
#: m: an offset held above this on a normal point is a phantom.
PHANTOM_M = 8.0


def _labelled(period: float | None, data_dir: str | None) -> list[tuple]:
    out = []
    # Nevada, natively 0.5 Hz, counts at both rates (as in the figures docs/ quote).
    for _, data, cols, cmap, _ in validation_positions(period, data_dir, keep_native=True):
        labelled = inject_grad(data, seed=0, columns=cmap)
        fixes = to_fixes(labelled[cols], cmap)
        usable = np.flatnonzero(stream_reasons(fixes, min_step_s=MIN_STEP_S) == "")
        out.append((fixes, usable, labelled["label_bias"].to_numpy()))
    return out


def held_shares(params: PipelineParams, cases: list[tuple]) -> dict[str, float]:
    """Percent of normal / jump / noise points with an offset above ``PHANTOM_M``."""
    offset_k = pipeline_feature_names(params).index("offset_norm")
    held = dict.fromkeys(KINDS, 0)
    total = dict.fromkeys(KINDS, 0)
    for fixes, usable, bias in cases:
        prepared = grad_points(fixes.iloc[usable], params.max_gap_s)
        pts = prepared.points
        # A point's kind: the fault of any row it stands for, else normal.
        kind = np.full(len(pts), "none", dtype=object)
        rows = np.flatnonzero(prepared.row_point >= 0)
        for j, p in zip(rows, prepared.row_point[rows], strict=True):
            if bias[usable[j]] != "none":
                kind[p] = bias[usable[j]]
        t, lat, lon = (pts[c].to_numpy(np.float64) for c in ("t", "lat", "lon"))
        nan = np.full(len(pts), np.nan)
        for k, sl in prepared.segment_slices():
            frame = prepared.segment_frames[k]
            f = grad_features(params, frame, t[sl], lat[sl], lon[sl], nan[sl], nan[sl]).features
            # Features are compressed with a signed log1p; the norm is >= 0.
            over = np.expm1(f[:, offset_k]) > PHANTOM_M
            for name in KINDS:
                mask = kind[sl] == name
                held[name] += int(over[mask].sum())
                total[name] += int(mask.sum())
    return {name: 100.0 * held[name] / max(total[name], 1) for name in KINDS}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--set", action="append", default=[], help="FIELD=VALUE[,FIELD=VALUE...]")
    parser.add_argument("--data-dir", default=None)
    args = parser.parse_args()
    rates = {"native": None, "0.5 Hz": 2.0}
    cases = {label: _labelled(period, args.data_dir) for label, period in rates.items()}
    print(
        "| offset settings | rate | normal points held (phantom) | jump points held | noise points held |"
    )
    print("|---|---|---|---|---|")
    for spec in args.set or [""]:
        changes = {k: float(v) for k, v in (kv.split("=") for kv in spec.split(",") if kv)}
        base = PipelineParams()
        params = dataclasses.replace(base, offset=dataclasses.replace(base.offset, **changes))
        for label in rates:
            s = held_shares(params, cases[label])
            print(
                f"| {spec or 'defaults'} | {label} | {s['none']:.1f} % | {s['jump']:.1f} % "
                f"| {s['noise']:.1f} % |"
            )


if __name__ == "__main__":
    main()

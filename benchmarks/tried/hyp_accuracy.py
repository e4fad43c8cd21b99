"""Phantom / jump-held of the shipped tracker vs the switching-Kalman prototype (offset_hypotheses)."""
from __future__ import annotations
import argparse, sys, time
from pathlib import Path
import numpy as np
sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
sys.path.insert(0, str(Path(__file__).resolve().parent))
from tracker_accuracy import drives, accuracy, Detector, inject_grad, to_fixes, segment_features, pipeline_feature_names
from offset_hypotheses import HypParams, offsets

def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--period", type=float, default=0.0)
    ap.add_argument("--set", default="", help="k=v,... HypParams")
    ap.add_argument("--only", default="")
    ap.add_argument("--skip", default="")
    a = ap.parse_args()
    kw = {k: float(v) for k, v in (s.split("=") for s in a.set.split(",") if s)}
    if "beam" in kw: kw["beam"] = int(kw["beam"])
    prm = HypParams(**kw)
    det = Detector(None)
    names = pipeline_feature_names(det.model_.params)
    cols = [names.index("offset_east"), names.index("offset_north")]
    print(prm)
    for name, table, cmap in drives(None if a.period == 0 else a.period):
        if a.only and a.only not in name: continue
        if a.skip and a.skip in name: continue
        t0 = time.time()
        res = []
        for lab in (inject_grad(table, seed=0, columns=cmap), None):
            src = lab if lab is not None else table
            fx = to_fixes(src, cmap)
            ship = np.zeros((len(fx), 2)); hyp = np.zeros((len(fx), 2))
            for rows, pts, vals in segment_features(det, fx):
                ship[rows] = vals[:, cols]
                t = pts["t"].to_numpy(float); dt = np.diff(t, prepend=t[0])
                hyp[rows] = offsets(dt, pts["east"].to_numpy(float), pts["north"].to_numpy(float), prm)
            res.append((fx, ship, hyp))
        lab = inject_grad(table, seed=0, columns=cmap)
        ps, hs, n = accuracy(lab, table, cmap, res[0][1])
        ph, hh, _ = accuracy(lab, table, cmap, res[0][2])
        cs = float(np.mean((np.abs(res[1][1]) > 8).any(axis=1)))
        ch = float(np.mean((np.abs(res[1][2]) > 8).any(axis=1)))
        print(f"{name:24s} phantom ship {100*ps:5.1f} hyp {100*ph:5.1f} | held ship {100*hs:5.1f} hyp {100*hh:5.1f} | untouched ship {100*cs:5.2f} hyp {100*ch:5.2f} | {time.time()-t0:.0f}s", flush=True)

if __name__ == "__main__":
    main()

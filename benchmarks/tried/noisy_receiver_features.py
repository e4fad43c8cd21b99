"""Which of the network's inputs make it flag a noisy receiver's clean fixes.

The shipped network on six fresh 15-minute simulated drives (seed 4242, positions
only) from the simulator's logger and from a city-like receiver (5 m of slowly
varying error over 20 s, 1.5 m of heavy-tailed epoch noise): the share of clean
fixes whose at-once P(anomaly) reaches the model's threshold (NumPy reference GRU
on the pipeline's features), then the same with one feature, or one group, set to
its median on the logger's drives for the whole drive (``median``), or its
deviations from that median halved (``halved``). What drops the share most is what
the network reads as a fault on a noisy receiver. Simulated drives only:

    python benchmarks/tried/noisy_receiver_features.py [--hz 1]
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

from gradgps._data.simulator import SimulatorParams, simulate_fleet
from gradgps._grad.detector import Detector
from gradgps._grad.gru import reference_stream
from gradgps._grad.model_io import load_model
from gradgps._grad.pipeline import pipeline_feature_names
from gradgps._tracks.track import ColumnMap, to_fixes

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # benchmarks/, for the helpers
from _segment_features import segment_features

POSITIONS = ColumnMap(track="track", time="t", lat="lat", lon="lon", speed="", heading="")
CITY = SimulatorParams(gnss_correlated_sigma=5.0, gnss_correlation_time=20.0, gnss_white_sigma=1.5)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--hz", type=float, default=1.0)
    args = parser.parse_args()
    det = Detector()
    names = pipeline_feature_names(det.model_.params)
    weights, config = load_model(det.model_.path)
    mean, std = np.array(config["scaler"]["mean"]), np.array(config["scaler"]["std"])
    threshold = det.model_.params.thresholds_at(1.0 / args.hz)[0]

    def features(params: SimulatorParams) -> list[np.ndarray]:
        sim = simulate_fleet(6, 15.0, args.hz, 4242, imu=False, params=params)
        fixes = to_fixes(sim[["track", "t", "lat", "lon"]], POSITIONS)
        return [f for _, _, f in segment_features(det, fixes, decompress=False)]

    logger, city = features(SimulatorParams()), features(CITY)
    medians = np.median(np.concatenate(logger), axis=0)

    def flagged(segments: list[np.ndarray], columns: list[int], shrink: float | None) -> float:
        hits = total = 0
        for f in segments:
            g = f.copy()
            if columns:
                g[:, columns] = (
                    medians[columns]
                    if shrink is None
                    else medians[columns] + (g[:, columns] - medians[columns]) * shrink
                )
            pred, _ = reference_stream(weights, mean, std, g)
            hits += int((pred.anomaly >= threshold).sum())
            total += len(g)
        return 100.0 * hits / total

    def index(*wanted: str) -> list[int]:
        return [names.index(n) for n in wanted]

    groups = {
        "MS-SW (no REMA)": [
            i
            for i, n in enumerate(names)
            if n.split("_")[0] in ("east", "north") and "rema" not in n
        ],
        "REMA": [i for i, n in enumerate(names) if "rema" in n],
        "offset tracker": list(
            range(names.index("offset_east"), names.index("previous_offset_revised") + 1)
        ),
        "motion model": list(range(names.index("motion_innovation"), len(names))),
        **{n: index(n) for n in names[names.index("offset_east") :]},
    }
    print(
        f"{args.hz:g} Hz, at-once flags on clean fixes: logger {flagged(logger, [], None):.2f} %, "
        f"city receiver {flagged(city, [], None):.2f} %"
    )
    print("| city receiver, with | median | halved |")
    print("|---|---|---|")
    for name, columns in groups.items():
        print(
            f"| {name} | {flagged(city, columns, None):.2f} % | {flagged(city, columns, 0.5):.2f} % |"
        )


if __name__ == "__main__":
    main()

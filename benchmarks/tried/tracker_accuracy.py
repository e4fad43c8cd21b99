"""How right the offset tracker is, against the injected truth, without the network.

A change to the offset tracker changes the network's inputs, so judging it by the
detector's F1 needs a retrain, and one retrain moves the validation numbers by as
much as the changes tried so far (docs/deviations.md, "both of the rows above, with
a retrained network"). This judges the tracker's own output instead, against what
protocol ``grad`` (seed 0) wrote, positions only (``--variant +speed+heading``: with the
reported speed and heading, where a drive set has them):

* **phantom**: the share of *normal* fixes (no injected fault in either channel)
  where the tracker holds an offset above 8 m in a channel: a
  clean fix read as displaced, what the network then flags or learns to distrust;
* **jump held**: the share of fixes inside injected *jump* faults, per faulty
  channel, where the tracker's offset is within 8 m or a quarter of the true
  offset (whichever is larger) of the true offset in that channel: the fault the
  tracker exists to remember.

On the real validation drives (``--period 0``: native rate; ``--period 2``: 0.5
Hz), never the test splits, and on fresh simulated drives at 10, 1 and 0.5 Hz
(seed 4242, 6 x 15 minutes, as ``hangover_check.py`` draws them). The tracker
runs alone on the detector's segments (positions only, it takes no velocity but a
reported one, so this is what the pipeline computes) with the default settings,
``--model``'s, and ``--set`` overrides (``--set sigma_m=3,fault_s=45``).
``--where`` adds, per set of drives, the phantom share on the same drives
untouched and where the phantoms of the injected drives sit: how many fixes after
an episode's end (1, 2-3, 4-10, 11-30, 31-100, more). Run with the sources to judge
on ``PYTHONPATH``:

    python benchmarks/tried/tracker_accuracy.py [--model DIR] [--period 0|2] [--where]
        [--set K=V,...] [--skip NAME] [--variant positions|+speed|+speed+heading]
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Iterator
from dataclasses import replace
from pathlib import Path

import numpy as np
import pandas as pd

from gradgps._data.inject import inject_grad
from gradgps._data.simulator import simulate_fleet
from gradgps._eval.robustness import _variant_columns
from gradgps._grad.defaults import MIN_STEP_S, grad_points
from gradgps._grad.detector import Detector
from gradgps._grad.offset import (
    OFFSET_FEATURES,
    OffsetParams,
    _Hypothesis,
    _reference_channel,
    offset_features,
)
from gradgps._grad.pipeline import PipelineParams
from gradgps._tracks.preprocess import stream_reasons
from gradgps._tracks.track import ColumnMap, to_fixes

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # benchmarks/, for the helpers
sys.path.insert(0, str(Path(__file__).resolve().parent))  # for error_places
from _validation_drives import validation_positions
from error_places import episode_distances

POSITIONS = ColumnMap(track="track", time="t", lat="lat", lon="lon", speed="", heading="")
THRESHOLD_M = 8.0
_M_PER_DEG = 111_320.0


def drives(
    period: float | None, variant: str = "positions"
) -> Iterator[tuple[str, pd.DataFrame, ColumnMap]]:
    """(name, table, column map): simulated drives, then the validation drives, in
    ``variant``'s columns (drive sets without them left out)."""
    for hz in (10.0, 1.0, 0.5):
        sim = simulate_fleet(6, 15.0, hz, 4242, imu=False)
        picked = _variant_columns(sim, to_fixes(sim).attrs["columns"], variant)
        assert picked is not None  # the simulator reports speed and heading
        yield f"simulated {hz:g} Hz", sim[picked[0]], picked[1]
    for name, data, _, cmap, _ in validation_positions(period, keep_native=True, variant=variant):
        yield name, data, cmap


def tracker_features(
    params: OffsetParams, max_gap_s: float, fixes: pd.DataFrame, fill: float = 0.0
) -> np.ndarray:
    """Per fix of ``fixes``: the tracker's outputs (:data:`OFFSET_FEATURES`), the tracker
    run alone on the detector's segments (it takes no other velocity than a reported
    speed and heading, so this is what the pipeline computes); ``fill`` where a fix is
    not used."""
    out = np.full((len(fixes), len(OFFSET_FEATURES)), fill)
    usable = np.flatnonzero(stream_reasons(fixes, min_step_s=MIN_STEP_S) == "")
    prepared = grad_points(fixes.iloc[usable], max_gap_s)
    values = np.zeros((len(prepared.points), len(OFFSET_FEATURES)))
    for _, sl in prepared.segment_slices():
        pts = prepared.points.iloc[sl]
        t = pts["t"].to_numpy(np.float64)
        east, north = (pts[c].to_numpy(np.float64) for c in ("east", "north"))
        speed, heading = (
            pts[c].to_numpy(np.float64) if c in pts else None for c in ("speed", "heading")
        )
        values[sl] = offset_features(
            np.diff(t, prepend=t[0]), east, north, speed, heading, params=params
        )
    out[usable] = prepared.to_rows(values, fill=fill)
    return out


def tracker_offsets(params: OffsetParams, max_gap_s: float, fixes: pd.DataFrame) -> np.ndarray:
    """Per fix of ``fixes``: the tracker's offset east and north (m), 0 where a fix is not
    used (:func:`tracker_features`)."""
    return tracker_features(params, max_gap_s, fixes)[:, :2]


AFTER_BINS = (1, 2, 4, 11, 31, 101)  # fixes after an episode's end: 1, 2-3, ..., 101+


def accuracy(
    labelled: pd.DataFrame, table: pd.DataFrame, cmap: ColumnMap, offset: np.ndarray
) -> tuple[float, float, int]:
    """(phantom share of normal fixes, jump-held share of jump-faulty channel fixes,
    jump-faulty channel fixes) of the tracker's ``offset`` on ``labelled``, the
    injected ``table``."""
    lat_true = table[cmap.lat].to_numpy(np.float64)
    cos = np.cos(np.radians(lat_true))
    true = (
        np.stack(
            [
                (labelled[cmap.lon].to_numpy(np.float64) - table[cmap.lon].to_numpy()) * cos,
                labelled[cmap.lat].to_numpy(np.float64) - lat_true,
            ],
            1,
        )
        * _M_PER_DEG
    )
    normal = labelled["label_anomaly"].to_numpy() == 0
    phantom = float(np.mean((np.abs(offset[normal]) > THRESHOLD_M).any(axis=1)))
    held, count = 0, 0
    for c, channel in enumerate(("lon", "lat")):  # east is longitude, north latitude
        jump = labelled[f"label_bias_{channel}"].to_numpy() == "jump"
        error = np.abs(offset[jump, c] - true[jump, c])
        held += int(np.sum(error <= np.maximum(THRESHOLD_M, 0.25 * np.abs(true[jump, c]))))
        count += int(jump.sum())
    return phantom, held / max(count, 1), count


def phantom_places(labelled: pd.DataFrame, fixes: pd.DataFrame, offset: np.ndarray) -> list[int]:
    """The phantoms of the tracker's ``offset`` on the injected drives, counted by how
    many fixes after an episode's end they sit, in :data:`AFTER_BINS`."""
    faulty = labelled["label_anomaly"].to_numpy() == 1
    phantom = (np.abs(offset) > THRESHOLD_M).any(axis=1) & ~faulty
    _, after, _ = episode_distances(faulty, fixes["track"].to_numpy())
    counts = np.histogram(after[phantom], bins=[*AFTER_BINS, np.iinfo(np.int64).max])[0]
    return [int(n) for n in counts]


def beam_trace(
    params: OffsetParams, points: pd.DataFrame, channel: str
) -> list[tuple[int, list[_Hypothesis]]]:
    """The readable tracker's beam after every fix of one segment's prepared ``points``
    (``t``, ``east``, ``north``) in ``channel``, positions only: ``(fix, hypotheses best
    first)``, for the scripts that read why the tracker holds or lets go an offset."""
    t = points["t"].to_numpy(np.float64)
    east, north = points["east"].to_numpy(np.float64), points["north"].to_numpy(np.float64)
    repeated = np.r_[False, (np.diff(east) == 0) & (np.diff(north) == 0)]
    trace: list[tuple[int, list[_Hypothesis]]] = []
    _reference_channel(
        params,
        np.diff(t, prepend=t[0]),
        east if channel == "east" else north,
        np.full(len(t), np.nan),
        repeated,
        trace,
    )
    return trace


def tracker_settings(base: OffsetParams, settings: str) -> OffsetParams:
    """``base`` with the overrides of a ``--set`` option (``"sigma_m=3,fault_s=45"``)."""
    overrides = {k: float(v) for k, v in (kv.split("=") for kv in settings.split(",") if kv)}
    return replace(base, **overrides)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--model", default=None)
    parser.add_argument("--period", type=float, default=0.0, help="seconds; 0 = native")
    parser.add_argument("--where", action="store_true", help="untouched drives, and where")
    parser.add_argument("--set", default="", help="tracker settings k=v,... over the model's")
    parser.add_argument(
        "--variant", default="positions", help="columns: positions, +speed, +speed+heading"
    )
    parser.add_argument("--skip", default="", help="leave out drive sets whose name holds this")
    args = parser.parse_args()
    params = Detector(args.model).model_.params if args.model else PipelineParams()
    tracker = tracker_settings(params.offset, args.set)
    print(tracker)
    head = "| drives | normal fixes with a phantom offset | jump fixes held (channel fixes) |"
    rule = "|---|---|---|"
    if args.where:
        head += " untouched drives: phantoms | phantoms 1 / 2-3 / 4-10 / 11-30 / 31-100 / more fixes after an episode |"
        rule += "---|---|"
    print(head)
    print(rule)
    for name, table, cmap in drives(None if args.period == 0 else args.period, args.variant):
        if args.skip and args.skip in name:
            continue
        labelled = inject_grad(table, seed=0, columns=cmap)
        fixes = to_fixes(labelled, cmap)
        offset = tracker_offsets(tracker, params.max_gap_s, fixes)
        phantom, held, count = accuracy(labelled, table, cmap, offset)
        row = f"| {name} | {100 * phantom:.2f} % | {100 * held:.1f} % ({count:,}) |"
        if args.where:
            untouched = tracker_offsets(tracker, params.max_gap_s, to_fixes(table, cmap))
            clean_share = float(np.mean((np.abs(untouched) > THRESHOLD_M).any(axis=1)))
            counts = phantom_places(labelled, fixes, offset)
            row += f" {100 * clean_share:.2f} % | {' / '.join(str(n) for n in counts)} |"
        print(row)


if __name__ == "__main__":
    main()

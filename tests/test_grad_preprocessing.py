"""GRAD's preprocessing is spelled once: detection, training and the report merge the same points."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from gradgps import Detector, LocalFrame
from gradgps._grad.defaults import MIN_STEP_S, grad_points
from gradgps._grad.pipeline import PipelineParams
from gradgps._run.report import ReportInputs, figures
from gradgps._train.grad import labelled_sequences

# Odd inputs on purpose: the Detector says so (gradgps.InputWarning); what is tested here
# is the answer it gives all the same.
pytestmark = pytest.mark.filterwarnings("ignore::gradgps.InputWarning")


def _fixes() -> pd.DataFrame:
    n = 40
    t = np.arange(n, dtype=float)
    t[20] = t[19] + MIN_STEP_S / 2  # one instant, reported twice (the same fix)
    east = 10.0 * np.arange(n)
    east[20] = east[19]
    lat, lon = LocalFrame(41.25, -95.98).to_geodetic(east, np.zeros(n))
    return pd.DataFrame({"track": "a", "t": t, "lat": lat, "lon": lon})


def _drawn_sizes(fixes: pd.DataFrame) -> set[int]:
    """How many points each line of the report's segment figures draws for ``fixes``."""
    det = Detector()
    drawn = figures(ReportInputs(fixes, det.detect(fixes), det.model_.params))
    try:
        lines = [line for _, _, fig in drawn[1:] for ax in fig.axes for line in ax.get_lines()]
        return {len(line.get_xdata()) for line in lines}
    finally:
        import matplotlib.pyplot as plt

        for _, _, fig in drawn:
            plt.close(fig)


def test_report_draws_the_segments_a_time_glitch_makes() -> None:
    """A fix set aside for its time at a new position begins a new segment at the next
    usable fix (:func:`gradgps._tracks.preprocess.time_glitch_breaks`): the report draws
    the two segments detection scored."""
    fixes = _fixes()
    fixes.loc[20, "lat"] += 1e-4  # the second report of the instant is another fix
    sizes = _drawn_sizes(fixes)
    assert {20, 19} <= sizes, sizes
    assert len(fixes) - 1 not in sizes


def test_training_sees_the_points_detection_sees() -> None:
    fixes = _fixes()
    params = PipelineParams()
    points = grad_points(fixes, params.max_gap_s).points
    assert len(points) == len(fixes) - 1  # the two fixes < 1 ms apart are one point
    labelled = fixes.assign(label_anomaly=0, label_bias="none")
    sequences = labelled_sequences(labelled, params)
    assert sum(len(s[1]) for s in sequences) == len(points)


def test_report_draws_the_points_detection_scored() -> None:
    fixes = _fixes()
    sizes = _drawn_sizes(fixes)
    assert len(fixes) not in sizes
    assert len(fixes) - 1 in sizes


def test_the_detector_does_not_interpolate_short_gaps_and_the_docs_say_so() -> None:
    from pathlib import Path

    fixes = _fixes()
    fixes.loc[30:, "t"] += 2.0  # a short gap (below max_gap_s): one segment, nothing filled in
    params = PipelineParams()
    assert params.max_gap_s > 3.0
    points = grad_points(fixes, params.max_gap_s).points
    assert not points["interpolated"].any()
    assert points["segment"].nunique() == 1
    doc = (Path(__file__).resolve().parents[1] / "docs" / "architecture.md").read_text()
    assert "short gaps interpolated" not in doc
    assert "short gaps **not**\n  interpolated" in doc

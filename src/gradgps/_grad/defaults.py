"""GRAD's own tuned defaults for REMA and the time classifier.

With untuned settings REMA loses a moving car after its first long fault, and
its features would tell the network nothing from then on. These values are
what ``gradgps tune-rema --dataset driveplotr`` chose on the driveplotr
validation split (injection seeds 0, 1, 2; docs/rema.md): trend mode with
speed/heading, 8 m floor, sensitivity 5, bounds growing 0.5 m per
consecutive outlier; permanent after 6 flagged points. GRAD adds bounds on
how long REMA may stay diverged (re-acquire after 3 consistent steps, at
most 20 flagged points; docs/deviations.md).

GRAD owns them, and they are spelled only here: the ``rema`` baseline
(:class:`gradgps._baselines.rema_detector.RemaDetector`) takes its defaults
from this module (:func:`tuned_rema_params`, the tuning's choice without
GRAD's re-acquisition bounds), never the other way round. A retuned
baseline is a settings file (``gradgps tune-rema``), which changes nothing
here; GRAD's shipped model was trained on features computed with these
settings.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pandas as pd

from .._result import STEP_TOLERANCE_S
from .._tracks.preprocess import Prepared, preprocess
from .rema import RemaParams
from .time_classifier import TimeParams

__all__ = ["grad_rema_params", "grad_time_params", "tuned_rema_params"]


def tuned_rema_params() -> RemaParams:
    """The REMA settings ``gradgps tune-rema --dataset driveplotr`` chose (docs/rema.md).

    The ``rema`` baseline's defaults as they are; GRAD's with its
    re-acquisition bounds added (:func:`grad_rema_params`).
    """
    return RemaParams(
        alpha=0.3,
        alpha_min=0.2,
        alpha_max=0.9,
        punish=0.2,
        reward=0.02,
        slide_size=6,
        sensitivity=5.0,
        min_margin=8.0,
        mode="trend",
        run_growth=0.5,
    )


def grad_rema_params() -> RemaParams:
    """REMA settings of GRAD's pipeline (:class:`gradgps._grad.pipeline.PipelineParams`):
    the tuned ones, re-acquiring after 3 consistent steps and after at most 20
    flagged points, so that no long fault leaves REMA diverged (and the
    GRU's REMA features meaningless) for the rest of a drive."""
    return replace(tuned_rema_params(), reacquire_after=3, max_run=20)


def grad_time_params() -> TimeParams:
    """Time-classifier settings of GRAD's pipeline."""
    return TimeParams(permanent_run=6, episode_gap=15, intermittent_bursts=2)


#: Shortest time step between two fixes of a track. A segment's sampling
#: period comes from its first steps and its windows hold ``window_s / period``
#: fixes, so a step of a nanosecond (clock jitter, a corrupted timestamp) would
#: ask for billions of slots. No receiver reports faster than 1 kHz: a closer
#: fix is flagged invalid, in every mode (see ``stream_reasons``).
MIN_STEP_S = 1e-3

#: A fix farther than this from its segment's first fix starts a new segment
#: (with its own local frame): the projection is exact to 1 mm within 100 km.
FRAME_RADIUS_M = 100_000.0


def grad_points(
    fixes: pd.DataFrame, max_gap_s: float, breaks: np.ndarray | None = None
) -> Prepared:
    """GRAD's preprocessing, the one spelling that detection, training and the report share.

    Each track in time order, fixes less than :data:`MIN_STEP_S` apart merged,
    segments cut at gaps longer than ``max_gap_s`` and at a fix more than
    :data:`FRAME_RADIUS_M` from the segment's first one (each segment in its
    own frame: ``Prepared.segment_frames``); short gaps are *not*
    interpolated (the Detector sees the fixes as they came, as a stream does).
    Steps are compared with :data:`gradgps._result.STEP_TOLERANCE_S`, as
    :func:`gradgps._tracks.preprocess.stream_reasons` does, so rows it
    passes are never merged here. ``breaks``: rows that begin a segment whatever the
    gap before them (:func:`gradgps._tracks.preprocess.time_glitch_breaks`).
    """
    return preprocess(
        fixes,
        max_gap_s=max_gap_s,
        interpolate=False,
        min_step_s=MIN_STEP_S - STEP_TOLERANCE_S,
        frame_radius_m=FRAME_RADIUS_M,
        breaks=breaks,
    )

"""GRAD's own tuned defaults for REMA and the time classifier.

With untuned settings REMA loses a moving car after its first long fault, and
its features would tell the network nothing from then on. These values are
what ``gradgps tune-rema --dataset driveplotr`` chose on the driveplotr
validation split (injection seeds 0, 1, 2; docs/rema.md): trend mode with
speed/heading, 8 m floor, sensitivity 5, bounds growing 0.5 m per
consecutive outlier; permanent after 6 flagged points.

They start out equal to the ``rema`` baseline's defaults
(:class:`gradgps._baselines.rema_detector.RemaDetector`), but GRAD owns them:
retuning the baseline does not change GRAD, whose shipped model was trained
on features computed with these settings.
"""

from __future__ import annotations

from .rema import RemaParams
from .time_classifier import TimeParams

__all__ = ["grad_rema_params", "grad_time_params"]


def grad_rema_params() -> RemaParams:
    """REMA settings of GRAD's pipeline (:class:`gradgps._grad.pipeline.PipelineParams`)."""
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
        reacquire_after=3,
        max_run=20,
    )


def grad_time_params() -> TimeParams:
    """Time-classifier settings of GRAD's pipeline."""
    return TimeParams(permanent_run=6, episode_gap=15, intermittent_bursts=2)

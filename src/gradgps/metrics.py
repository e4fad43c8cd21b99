"""Benchmark metrics (public): pointwise scores, confusion matrices, events, false alarms, RMSE.

``from gradgps import metrics``; see :mod:`gradgps._eval.metrics` for the definitions.
"""

from ._eval.metrics import (
    class_scores,
    confusion_matrix,
    detection_delays,
    event_recall,
    false_alarms_per_hour,
    rmse_m,
    type_accuracy,
    window_scores,
)

__all__ = [
    "class_scores",
    "confusion_matrix",
    "detection_delays",
    "event_recall",
    "false_alarms_per_hour",
    "rmse_m",
    "type_accuracy",
    "window_scores",
]

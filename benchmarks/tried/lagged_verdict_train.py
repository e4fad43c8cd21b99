"""Train a network whose verdict comes one (or more) fixes late: an experiment for issue 13, not the product.

Why: on the validation drives, 106 of the shipped model's 127 false positives
(positions only, native rate) sit 1-3 fixes after an injected fault ends, 61
at the very first fix (``benchmarks/false_positive_places.py``). From
positions alone a fix 10-20 m off after a noise run and the track read alike
until the next fix shows which way the track goes. This script trains the
recipe's network exactly as ``gradgps train`` does, except that every label
moves one point later within its sequence: the output at point ``i`` judges
point ``i - 1`` (the first point of a sequence is not scored). Score it with
``lagged_verdict_check.py --lag 1``. ``GRADGPS_LAG=k`` in the environment
moves them ``k`` points later instead (score with ``--lag k``): at 0.5 Hz
one fix late is two seconds, and the question is whether a second fix of
look-ahead settles what the first leaves open. Run (arguments as ``gradgps
train``'s):

    [GRADGPS_LAG=2] python benchmarks/tried/lagged_verdict_train.py train --dataset recipe \\
        --max-epochs 30 --time-budget 3600 --members 1 --seed 0 -o /tmp/model_lag
"""

from __future__ import annotations

import os
import sys
from typing import Any

import numpy as np

import gradgps._train.grad as grad_training
from gradgps._cli import main
from gradgps._train.labels import IGNORE_LABEL

_labelled_sequences = grad_training.labelled_sequences


LAG = int(os.environ.get("GRADGPS_LAG", "1"))


def moved_later(labels: np.ndarray, lag: int) -> np.ndarray:
    """``labels`` moved ``lag`` points later: point ``i`` carries point ``i - lag``'s label,
    the first ``lag`` points none (:data:`IGNORE_LABEL`)."""
    late = np.full_like(labels, IGNORE_LABEL)
    late[lag:] = labels[: len(labels) - lag]
    return late


def fixes_late(*args: Any, **kwargs: Any) -> list[tuple[np.ndarray, np.ndarray, np.ndarray]]:
    """The recipe's sequences with the anomaly and bias labels moved :data:`LAG` points later."""
    return [
        (features, moved_later(anomaly, LAG), moved_later(bias, LAG))
        for features, anomaly, bias in _labelled_sequences(*args, **kwargs)
    ]


if __name__ == "__main__":
    grad_training.labelled_sequences = fixes_late  # type: ignore[assignment]
    main(sys.argv[1:])

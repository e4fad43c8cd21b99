"""Train a network whose verdict comes one fix late: an experiment for issue 13, not the product.

Why: on the validation drives, 106 of the shipped model's 127 false positives
(positions only, native rate) sit 1-3 fixes after an injected fault ends, 61
at the very first fix (``benchmarks/false_positive_places.py``). From
positions alone a fix 10-20 m off after a noise run and the track read alike
until the next fix shows which way the track goes. This script trains the
recipe's network exactly as ``gradgps train`` does, except that every label
moves one point later within its sequence: the output at point ``i`` judges
point ``i - 1`` (the first point of a sequence is not scored). Score it with
``lagged_verdict_check.py --lag 1``. Run (arguments as ``gradgps train``'s):

    python benchmarks/tried/lagged_verdict_train.py train --dataset recipe --max-epochs 30 \\
        --time-budget 3600 --members 1 --seed 0 -o /tmp/model_lag
"""

from __future__ import annotations

import sys
from typing import Any

import numpy as np

import gradgps._train.grad as grad_training
from gradgps._cli import main
from gradgps._train.labels import IGNORE_LABEL

_labelled_sequences = grad_training.labelled_sequences


def one_fix_late(*args: Any, **kwargs: Any) -> list[tuple[np.ndarray, np.ndarray, np.ndarray]]:
    """The recipe's sequences with the anomaly and bias labels moved one point later."""
    out = []
    for features, anomaly, bias in _labelled_sequences(*args, **kwargs):
        late_anomaly, late_bias = np.empty_like(anomaly), np.empty_like(bias)
        late_anomaly[0] = late_bias[0] = IGNORE_LABEL
        late_anomaly[1:], late_bias[1:] = anomaly[:-1], bias[:-1]
        out.append((features, late_anomaly, late_bias))
    return out


if __name__ == "__main__":
    grad_training.labelled_sequences = one_fix_late  # type: ignore[assignment]
    main(sys.argv[1:])

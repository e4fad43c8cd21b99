"""Running a detector on a benchmark's own tables.

A benchmark feeds the detectors tables it made itself (decimated drives, injected
faults, noisy receivers on purpose) to measure what they answer there; the
:class:`gradgps.InputWarning` a user's file earns is no news to it, and would only
interleave Python's warning lines with the tables it prints. The measurement is the
same either way: the warning changes no verdict.
"""

from __future__ import annotations

import warnings
from typing import Protocol

import pandas as pd

from .._exceptions import InputWarning

__all__ = ["detect_quietly"]


class _Detects(Protocol):
    def detect(self, fixes: pd.DataFrame) -> pd.DataFrame: ...


def detect_quietly(detector: _Detects, fixes: pd.DataFrame) -> pd.DataFrame:
    """``detector.detect(fixes)`` without its input warnings."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", InputWarning)
        return detector.detect(fixes)

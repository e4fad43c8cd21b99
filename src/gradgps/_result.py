"""What a detector says about one point, and the columns of a batch result.

Every detector returns the same columns (see docs/architecture.md, "Detector
interface") so benchmarks and the CLI treat them alike. A detector that does
not produce a quantity (a speed gate has no bias type) leaves it missing
(``None``) rather than inventing a value.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

__all__ = ["RESULT_COLUMNS", "PointResult", "ResultCounts"]

RESULT_COLUMNS = ("anomaly", "score", "bias_type", "time_type", "lat_clean", "lon_clean", "alert")


@dataclass(frozen=True)
class PointResult:
    """A streaming detector's verdict on one fix.

    ``anomaly`` and ``alert`` are 0/1; ``score`` in [0, 1] (nan for an
    unusable fix); ``bias_type``/``time_type`` ``None`` when the detector does
    not classify; ``lat_clean``/``lon_clean`` the position to use instead;
    ``invalid_reason`` is empty for a usable fix, else why it could not be
    used (it is then flagged and never enters the detector's state).
    """

    anomaly: int
    score: float
    bias_type: str | None
    time_type: str | None
    lat_clean: float
    lon_clean: float
    alert: int
    invalid_reason: str = ""

    @classmethod
    def invalid(cls, reason: str) -> PointResult:
        """The verdict on a fix that could not be used: flagged, no score, no position."""
        return cls(
            anomaly=1,
            score=math.nan,
            bias_type="none",
            time_type="none",
            lat_clean=math.nan,
            lon_clean=math.nan,
            alert=0,
            invalid_reason=reason,
        )


@dataclass(frozen=True)
class ResultCounts:
    """The counts every summary of a result shows (CLI line, report, follow), computed one way.

    ``anomalies`` counts every row with ``anomaly=1``, the unusable fixes
    (``invalid``) included, exactly as the output's ``anomaly`` column sums.
    """

    rows: int
    anomalies: int
    invalid: int
    alerts: int

    def __add__(self, other: ResultCounts) -> ResultCounts:
        return ResultCounts(
            self.rows + other.rows,
            self.anomalies + other.anomalies,
            self.invalid + other.invalid,
            self.alerts + other.alerts,
        )

    def text(self) -> str:
        """``"N rows, A anomalies (I invalid fixes), L alerts"``."""
        return (
            f"{self.rows:,} rows, {self.anomalies:,} anomalies "
            f"({self.invalid:,} invalid fixes), {self.alerts:,} alerts"
        )

    @classmethod
    def of(cls, result: Any) -> ResultCounts:
        """Counts of a result frame (columns ``anomaly``, ``invalid_reason``, ``alert``)."""
        return cls(
            rows=len(result),
            anomalies=int(result["anomaly"].sum()),
            invalid=int((result["invalid_reason"] != "").sum()),
            alerts=int(result["alert"].sum()),
        )

"""What a detector says about a fix: one schema and one invalid-row policy for every detector.

Every detector (GRAD and every baseline), the CLI, the report, the follow and
Redis outputs use the columns :data:`RESULT_COLUMNS` with the dtypes
:data:`RESULT_DTYPES` (docs/architecture.md, "Detector interface"). A
detector that does not produce a quantity (a speed gate has no bias type)
leaves it missing (``None``) rather than inventing a value.

**Invalid rows.** A fix whose time, latitude or longitude is missing, not
finite or out of range (and, in a stream, one whose time goes back) is not
usable. Every detector answers it the same way: ``anomaly=1``, its
``invalid_reason``, NaN ``score`` and clean position, ``alert=0``; it never
enters the detector's state. :func:`fix_reason` (one fix) and
:func:`invalid_reasons` (a table) say why; :func:`result_frame` applies the
policy to a batch result, :meth:`PointResult.invalid` to a streamed one.

Also here, because every layer needs them: the strict-JSON encoding of
non-finite floats in detector state (:func:`encode_floats`,
:func:`decode_floats`) and the F1 score (:func:`f1_score`).
"""

from __future__ import annotations

import math
import reprlib
from collections.abc import Iterable, Sequence
from dataclasses import astuple, dataclass
from typing import Any

import numpy as np
import pandas as pd
from numpy.typing import ArrayLike

__all__ = [
    "FIX_QUALITY_WORDS",
    "NO_FIX",
    "NO_SATELLITES",
    "NULL_ISLAND",
    "RESULT_COLUMNS",
    "RESULT_DTYPES",
    "STEP_TOLERANCE_S",
    "PointResult",
    "ResultCounts",
    "as_number",
    "decode_floats",
    "encode_floats",
    "f1_score",
    "fix_quality_code",
    "fix_reason",
    "invalid_reasons",
    "reading",
    "receiver_reason",
    "result_frame",
    "results_frame",
    "shown",
    "usable_point",
]

#: Result columns and their dtypes, in order.
RESULT_DTYPES: dict[str, str] = {
    "anomaly": "int8",
    "score": "float64",
    "bias_type": "object",
    "time_type": "object",
    "lat_clean": "float64",
    "lon_clean": "float64",
    "alert": "int8",
    "invalid_reason": "object",
}
RESULT_COLUMNS = tuple(RESULT_DTYPES)


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
    def invalid(cls, reason: str, *, classifies: bool = True) -> PointResult:
        """The verdict on a fix that could not be used: flagged, no score, no position.

        ``classifies``: the detector names bias and time types (``"none"``
        here); a detector that does not leaves them ``None``.
        """
        kind = "none" if classifies else None
        return cls(1, math.nan, kind, kind, math.nan, math.nan, 0, reason)


_new_object = object.__new__


def usable_point(
    anomaly: int,
    score: float,
    bias_type: str | None,
    time_type: str | None,
    lat_clean: float,
    lon_clean: float,
    alert: int,
) -> PointResult:
    """``PointResult(anomaly, score, ..., alert)`` of a usable fix (no ``invalid_reason``).

    The same object, made without the frozen dataclass's ``__init__``, which sets each
    field through ``object.__setattr__``: that took about a microsecond, a third of a
    streaming ``Detector.update``.
    """
    point: PointResult = _new_object(PointResult)
    point.__dict__.update(
        anomaly=anomaly,
        score=score,
        bias_type=bias_type,
        time_type=time_type,
        lat_clean=lat_clean,
        lon_clean=lon_clean,
        alert=alert,
        invalid_reason="",
    )
    return point


def as_number(value: object) -> float:
    """``value`` as a float; NaN for ``None`` or anything that is not a number."""
    if value is None:
        return math.nan
    try:
        return float(value)  # type: ignore[arg-type]
    except (TypeError, ValueError):
        return math.nan


def reading(value: object) -> float:
    """An optional reading (speed, heading, a channel): a finite number, else NaN (absent)."""
    number = as_number(value)
    return number if math.isfinite(number) else math.nan


#: Reason for a fix at exactly (0, 0), what receivers report before they have a position.
NULL_ISLAND = "position exactly (0, 0): no fix yet"
#: Reason for a fix whose receiver reports fix quality 0 (GGA 0, RMC ``V``, GPX ``none``).
NO_FIX = "receiver reports no fix"
#: Reason for a fix whose receiver reports 0 satellites in use.
NO_SATELLITES = "receiver reports no fix (0 satellites)"

#: Fix-quality words (lower case, spaces and dashes dropped) and their GGA-style code:
#: 0 = no fix. RMC status letters, GPX ``<fix>`` values and common logger words.
FIX_QUALITY_WORDS: dict[str, float] = {
    "v": 0.0,
    "n": 0.0,
    "none": 0.0,
    "nofix": 0.0,
    "invalid": 0.0,
    "nosolution": 0.0,
    "a": 1.0,
    "gps": 1.0,
    "fix": 1.0,
    "valid": 1.0,
    "2d": 1.0,
    "3d": 1.0,
    "2dfix": 1.0,
    "3dfix": 1.0,
    "d": 2.0,
    "dgps": 2.0,
    "dgnss": 2.0,
    "sbas": 2.0,
    "pps": 3.0,
    "rtk": 4.0,
    "rtkfixed": 4.0,
    "float": 5.0,
    "rtkfloat": 5.0,
    "e": 6.0,
    "dr": 6.0,
    "estimated": 6.0,
    "deadreckoning": 6.0,
}


def fix_quality_code(value: object) -> float:
    """A receiver's fix quality as a GGA-style number: 0 = no fix, NaN = not reported.

    Numbers are taken as they are (a GGA quality or a receiver's fix type);
    text is a number or one of :data:`FIX_QUALITY_WORDS` (``"V"``,
    ``"none"``, ``"3d"``...). Anything else is *not reported* (NaN), never an
    error: the receiver's fields are hints, and an unreadable one must not
    stop detection.
    """
    if value is None or isinstance(value, bool):
        return math.nan
    if isinstance(value, int | float | np.integer | np.floating):
        number = float(value)
        return number if math.isfinite(number) else math.nan
    text = str(value).strip().lower().replace(" ", "").replace("-", "").replace("_", "")
    try:
        number = float(text)
    except ValueError:
        return FIX_QUALITY_WORDS.get(text, math.nan)
    return number if math.isfinite(number) else math.nan


def receiver_reason(fix_quality: object = None, satellites: object = None) -> str:
    """Why the receiver's own fields say a fix is no fix (``""`` when they do not, or are absent).

    ``fix_quality`` as :func:`fix_quality_code` reads it (0: no fix);
    ``satellites`` a count (0: no fix). The scalar twin of the receiver
    checks in :func:`invalid_reasons`.
    """
    if fix_quality_code(fix_quality) == 0.0:
        return NO_FIX
    if as_number(satellites) == 0.0:
        return NO_SATELLITES
    return ""


#: Tolerance on a time step compared with a minimum step: timestamps such as
#: 1.7e9 + 0.001 s are not exact in float64, so a 1 ms step may read 0.99999 ms.
STEP_TOLERANCE_S = 1e-5


def fix_reason(
    t: float,
    lat: float,
    lon: float,
    last_t: float | None = None,
    min_step_s: float = 0.0,
    *,
    fix_quality: object = None,
    satellites: object = None,
) -> str:
    """Why one fix cannot be used (``""`` if it can); the scalar twin of :func:`invalid_reasons`.

    ``last_t``: the time of the stream's previous usable fix. A fix before it
    is invalid; with ``min_step_s`` > 0 (GRAD, which needs a sampling
    period) so is one not at least ``min_step_s`` after it. Without it a
    repeated time is a reading ``dt = 0`` after the previous one, as in batch.
    ``fix_quality``, ``satellites``: what the receiver reports, when it does
    (:func:`receiver_reason`); a fix it calls no fix is invalid.
    """
    if not math.isfinite(t):
        return "time missing or not finite"
    receiver = receiver_reason(fix_quality, satellites)
    if receiver:
        return receiver
    if not math.isfinite(lat):
        return "latitude missing or not finite"
    if abs(lat) > 90.0:
        return "latitude outside +-90"
    if not math.isfinite(lon):
        return "longitude missing or not finite"
    if abs(lon) > 180.0:
        return "longitude outside +-180"
    if lat == 0.0 and lon == 0.0:
        return NULL_ISLAND
    if last_t is not None:
        if min_step_s > 0.0 and t <= last_t:
            return "time not after the previous fix"
        if t < last_t:
            return "time before the previous fix"
        if min_step_s > 0.0 and t - last_t < min_step_s - STEP_TOLERANCE_S:
            return f"time less than {min_step_s * 1000:g} ms after the previous fix"
    return ""


def invalid_reasons(fixes: pd.DataFrame) -> np.ndarray:
    """Per row of canonical fixes: ``""`` for a usable fix, else why not (first problem found).

    The receiver's own verdict (canonical columns ``fix_quality`` and
    ``satellites``, where present) comes before any position problem: a
    no-fix epoch's missing position is explained by the receiver.
    """
    n = len(fixes)
    reason = np.full(n, "", dtype=object)
    t = fixes["t"].to_numpy(dtype=np.float64)
    lat = fixes["lat"].to_numpy(dtype=np.float64)
    lon = fixes["lon"].to_numpy(dtype=np.float64)
    none = np.zeros(n, dtype=bool)
    no_sats = (
        fixes["satellites"].to_numpy(dtype=np.float64, na_value=np.nan) == 0.0
        if "satellites" in fixes.columns
        else none
    )
    no_fix = (
        fixes["fix_quality"].to_numpy(dtype=np.float64, na_value=np.nan) == 0.0
        if "fix_quality" in fixes.columns
        else none
    )
    checks = (
        ((lat == 0.0) & (lon == 0.0), NULL_ISLAND),
        (~np.isfinite(lon), "longitude missing or not finite"),
        (np.isfinite(lon) & (np.abs(lon) > 180.0), "longitude outside +-180"),
        (~np.isfinite(lat), "latitude missing or not finite"),
        (np.isfinite(lat) & (np.abs(lat) > 90.0), "latitude outside +-90"),
        (no_sats, NO_SATELLITES),
        (no_fix, NO_FIX),
        (~np.isfinite(t), "time missing or not finite"),
    )
    # Later checks overwrite earlier ones, so the most basic problem (time) wins.
    for mask, text in checks:
        reason[mask] = text
    return reason


def result_frame(
    index: pd.Index,
    reason: ArrayLike,
    *,
    anomaly: ArrayLike,
    score: ArrayLike,
    lat_clean: ArrayLike,
    lon_clean: ArrayLike,
    bias_type: ArrayLike | None = None,
    time_type: ArrayLike | None = None,
    alert: ArrayLike | None = None,
) -> pd.DataFrame:
    """The batch result from per-row arrays, with the invalid-row policy applied.

    ``bias_type``/``time_type``/``alert`` left out: the detector does not
    produce them (``None``, ``None``, 0). Rows with a non-empty ``reason``
    get ``anomaly=1``, NaN score and clean position, ``alert=0``.
    """
    n = len(index)
    why = np.asarray(reason, dtype=object)
    invalid = why != ""
    none = np.full(n, None, dtype=object)

    def numbers(values: ArrayLike, dtype: type, fill: float) -> np.ndarray:
        out = np.array(values, dtype=np.float64)
        out[invalid] = fill
        return out.astype(dtype)

    return pd.DataFrame(
        {
            "anomaly": numbers(np.nan_to_num(np.asarray(anomaly, np.float64)), np.int8, 1),
            "score": numbers(score, np.float64, math.nan),
            "bias_type": none if bias_type is None else np.asarray(bias_type, dtype=object),
            "time_type": none if time_type is None else np.asarray(time_type, dtype=object),
            "lat_clean": numbers(lat_clean, np.float64, math.nan),
            "lon_clean": numbers(lon_clean, np.float64, math.nan),
            "alert": numbers(np.zeros(n) if alert is None else alert, np.int8, 0),
            "invalid_reason": why,
        },
        index=index,
    ).astype(RESULT_DTYPES)


def results_frame(results: Iterable[PointResult], index: pd.Index) -> pd.DataFrame:
    """The batch result from streamed verdicts, one per row of ``index``, in order."""
    rows = [astuple(r) for r in results]
    columns = list(zip(*rows, strict=True)) if rows else [()] * len(RESULT_COLUMNS)
    return pd.DataFrame(
        {
            name: pd.Series(list(values), dtype=RESULT_DTYPES[name], index=index)
            for name, values in zip(RESULT_COLUMNS, columns, strict=True)
        }
    )


_NON_FINITE = {"nan": math.nan, "inf": math.inf, "-inf": -math.inf}


def encode_floats(values: Iterable[Any] | None) -> list[float | str] | None:
    """Floats for strict JSON: non-finite ones as the strings ``"nan"``, ``"inf"``, ``"-inf"``."""
    if values is None:
        return None
    if isinstance(values, np.ndarray) and values.ndim == 1 and values.dtype.kind == "f":
        # A state array (thousands of values): one C loop, then only the few non-finite ones.
        listed: list[float | str] = values.tolist()
        for k in np.flatnonzero(~np.isfinite(values)).tolist():
            x = float(values[k])
            listed[k] = "nan" if math.isnan(x) else "inf" if x > 0 else "-inf"
        return listed
    out: list[float | str] = []
    for v in values:
        x = float(v)
        out.append(
            x if math.isfinite(x) else ("nan" if math.isnan(x) else "inf" if x > 0 else "-inf")
        )
    return out


def shown(value: Any) -> str:
    """A short ``repr`` of any value, for error messages about data that may be hostile: at
    most a few levels of nesting and tens of characters (a plain ``repr`` of a list nested
    thousands deep raises RecursionError; of a 5,000-digit integer, ValueError)."""
    try:
        return reprlib.repr(value)
    except (ValueError, RecursionError):
        return f"a {type(value).__name__}"


def decode_floats(values: Sequence[Any] | None) -> list[float] | None:
    """The inverse of :func:`encode_floats`; ``ValueError``/``TypeError`` on anything else."""
    if values is None:
        return None
    if isinstance(values, str | bytes) or not isinstance(values, Sequence):
        raise TypeError(f"{type(values).__name__} is not a list of numbers")
    out: list[float] = []
    for v in values:
        if isinstance(v, str):
            if v not in _NON_FINITE:
                raise ValueError(f"{shown(v)} is not a number")
            out.append(_NON_FINITE[v])
        elif isinstance(v, bool) or not isinstance(v, int | float):
            raise TypeError(f"{shown(v)} is not a number")
        else:
            out.append(float(v))
    return out


def f1_score(truth: ArrayLike, predicted: ArrayLike) -> float:
    """F1 of the positive (truthy) class, as scikit-learn's ``f1_score`` computes it.

    ``2 tp / (2 tp + fp + fn)``; when there is nothing positive in either
    (empty input included) it is 0.0, scikit-learn's ``zero_division`` default.
    """
    y = np.asarray(truth).astype(bool)
    p = np.asarray(predicted).astype(bool)
    tp = int(np.sum(y & p))
    denominator = int(np.sum(y)) + int(np.sum(p))
    return 2.0 * tp / denominator if denominator else 0.0


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

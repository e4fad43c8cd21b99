"""Multi-stage sliding-window (MS-SW) features, per point, causal, translation-invariant.

For each position channel (``east``, ``north``) three groups of features are
computed from the current and past points only, so a stream and a batch give
the same numbers (see ``docs/features.md`` for the table: name, window,
formula, unit, why):

* long window (``long_window_s``): least-squares line through the window's
  values against time -> slope (m/s), the line's value at the current time
  relative to the current value (m; the paper's "intercept" made
  translation-invariant) and the standard error of the fit (m);
* short window (``short_window_s``): std of the per-point velocity (m/s), RSI
  of the steps (0..100), range of the values (m), last step as a velocity
  (m/s);
* REMA (from :mod:`gradgps._grad.rema`): distance to the EMA (m), bound width (m,
  0 in the warm-up), flag, alpha.

Window lengths are in seconds and turned into points with the segment's
period, and every rate is divided by the period, so 1 Hz and 10 Hz data give
comparable values. No feature depends on where the track is: only
differences of positions enter, which is what lets a model trained in Omaha
run in Berlin.

Optional cross-channel cues (``speed_heading=True``): implied speed from the
last step minus the reported speed (m/s), and implied course minus the
reported heading (degrees, wrapped to [-180, 180), NaN below 0.5 m/s where a
course means nothing). They are NaN where speed/heading are missing.

Undefined values at the start of a segment (a slope from one point, an SE
from two) are 0, not NaN, so a model never sees NaN from the position
features.
"""

from __future__ import annotations

from dataclasses import dataclass

import numba
import numpy as np
from numpy.typing import ArrayLike, NDArray

from .._exceptions import ConfigError
from .rema import O_ALPHA, O_DISTANCE, O_FLAG, O_LOWER, O_UPPER, RemaParams, rema_batch_kernel

__all__ = [
    "FeatureParams",
    "feature_names",
    "features_reference",
    "segment_features",
]

FloatArray = NDArray[np.float64]

CHANNEL_FEATURES = (
    "slope",
    "intercept",
    "se",  # long window
    "std",
    "rsi",
    "range",
    "diff",  # short window
    "rema_distance",
    "rema_width",
    "rema_flag",
    "rema_alpha",  # REMA
)
N_CHANNEL = len(CHANNEL_FEATURES)
CROSS_FEATURES = ("speed_gap", "heading_gap")
MIN_COURSE_SPEED = 0.5  # m/s; below it a course from two fixes is noise


#: Most fixes a feature window holds (the long window at up to 33 Hz with the default
#: 30 s): a segment's state stays a few tens of kilobytes however close its fixes are.
MAX_WINDOW_POINTS = 1_000


@dataclass(frozen=True)
class FeatureParams:
    """Window lengths in seconds; ``speed_heading`` adds the two cross-channel cues."""

    long_window_s: float = 30.0
    short_window_s: float = 5.0
    speed_heading: bool = True

    def points(self, period: float) -> tuple[int, int]:
        """(long, short) window lengths in points for a segment sampled every ``period`` s."""
        if not (np.isfinite(period) and period > 0):
            raise ConfigError(f"segment period must be a positive number of seconds, got {period}")
        if not (0 < self.short_window_s <= self.long_window_s):
            raise ConfigError(
                "need 0 < short_window_s <= long_window_s, got "
                f"{self.short_window_s} and {self.long_window_s}"
            )
        # Capped so memory is bounded whatever the timestamps: at very high rates the
        # windows cover fewer seconds (the short one keeps its share of the long one).
        long_n = max(3, min(round(self.long_window_s / period), MAX_WINDOW_POINTS))
        short_n = max(
            2,
            min(
                round(self.short_window_s / period),
                round(MAX_WINDOW_POINTS * self.short_window_s / self.long_window_s),
            ),
        )
        return long_n, short_n


def feature_names(params: FeatureParams | None = None) -> list[str]:
    """Column names of :func:`segment_features`, in order."""
    prm = params or FeatureParams()
    names = [f"{ch}_{f}" for ch in ("east", "north") for f in CHANNEL_FEATURES]
    if prm.speed_heading:
        names += list(CROSS_FEATURES)
    return names


@numba.njit(cache=True, error_model="numpy", inline="always")
def history_push(hist: FloatArray, count: int, x: float) -> FloatArray:
    """Append the ``count``-th value (1-based) to a doubled ring; return the recent window.

    ``hist`` has length ``2 * H``; each value is written at ``p`` and ``p + H``
    so the last ``min(count, H)`` values are always one contiguous slice
    (oldest first), which keeps the feature loops free of modulo arithmetic.
    """
    size = hist.size // 2
    pos = (count - 1) % size
    hist[pos] = x
    hist[pos + size] = x
    m = min(count, size)
    return hist[pos + size - m + 1 : pos + size + 1]


# Sums may be reordered (so LLVM vectorises the window loops); no flag that
# assumes finite values, because NaN handling must stay exact. Agreement with
# the reference to 1e-9 is tested.
SUM_FASTMATH = {"reassoc", "contract"}


@numba.njit(cache=True, error_model="numpy", fastmath=SUM_FASTMATH)
def channel_features_step(
    win: FloatArray, long_n: int, short_n: int, period: float, rema_row: FloatArray, out: FloatArray
) -> None:
    """Features of one channel at the newest point from ``win``, the recent values (oldest first).

    Values enter relative to the newest one (translation invariance). The
    spreads (the fit's standard error, the std of the steps) are computed in
    two passes over the window, from explicit residuals: a one-pass
    ``E[x^2] - E[x]^2`` cancels catastrophically on a clean straight drive,
    where the spread is ~0 but the squares are large, and the square root
    then turns a 1e-16 relative error into a visible 1e-8 m.
    """
    total = win.size
    newest = win[total - 1]
    # Long window: least squares of value on point index, centred on the window.
    m = min(total, long_n)
    first = total - m
    sy = 0.0
    sky = 0.0
    for k in range(m):
        y = win[first + k] - newest
        sy += y
        sky += float(k) * y
    mean_y = sy / m
    mean_j = (m - 1) / 2.0
    sxx = m * (m * m - 1.0) / 12.0
    sxy = sky - mean_j * sy
    slope_pt = sxy / sxx if sxx > 0.0 else 0.0
    se = 0.0
    if m > 2:
        # Residuals from the line through (mean_j, mean_y) with slope slope_pt.
        ssr = 0.0
        for k in range(m):
            r = (win[first + k] - newest) - (mean_y + slope_pt * (float(k) - mean_j))
            ssr += r * r
        se = np.sqrt(ssr / (m - 2))
    out[0] = slope_pt / period
    out[1] = mean_y + slope_pt * (m - 1 - mean_j)
    out[2] = se
    # Short window: the last short_n steps (fewer at the start). The steps
    # telescope, so their sum is one difference; gains + losses = sum |step|.
    n_steps = min(total - 1, short_n)
    start = total - n_steps
    sd = newest - win[start - 1] if n_steps > 0 else 0.0
    moved = 0.0
    lo = newest
    hi = newest
    for k in range(start, total):
        moved += abs(win[k] - win[k - 1])
        lo = min(lo, win[k - 1])
        hi = max(hi, win[k - 1])
    gain = 0.5 * (moved + sd)
    loss = 0.5 * (moved - sd)
    std_v = 0.0
    if n_steps > 0:
        mean_d = sd / n_steps
        sdd = 0.0
        for k in range(start, total):
            r = win[k] - win[k - 1] - mean_d
            sdd += r * r
        std_v = np.sqrt(sdd / n_steps) / period
    out[3] = std_v
    out[4] = 100.0 * gain / (gain + loss) if gain + loss > 0.0 else 50.0
    out[5] = hi - lo
    out[6] = (newest - win[total - 2]) / period if total > 1 else 0.0
    # REMA.
    out[7] = rema_row[O_DISTANCE]
    width = rema_row[O_UPPER] - rema_row[O_LOWER]
    out[8] = width if np.isfinite(width) else 0.0
    out[9] = rema_row[O_FLAG]
    out[10] = rema_row[O_ALPHA]


@numba.njit(cache=True, error_model="numpy", inline="always")
def velocity_step(speed: float, heading: float, period: float) -> tuple[float, float]:
    """(east, north) metres a car at ``speed`` m/s on course ``heading`` degrees moves in ``period`` s.

    NaN when either is missing: REMA's ``trend`` mode then predicts from its
    own step EMA alone.
    """
    if not (np.isfinite(speed) and np.isfinite(heading)):
        return np.nan, np.nan
    h = np.radians(heading)
    return speed * np.sin(h) * period, speed * np.cos(h) * period


def velocity_steps(
    speed: ArrayLike | None, heading: ArrayLike | None, period: float, n: int
) -> tuple[FloatArray, FloatArray]:
    """:func:`velocity_step` over arrays (all NaN when speed or heading is absent)."""
    if speed is None or heading is None:
        return np.full(n, np.nan), np.full(n, np.nan)
    sp = _optional(speed, n, "speed")
    h = np.radians(_optional(heading, n, "heading"))
    return sp * np.sin(h) * period, sp * np.cos(h) * period


@numba.njit(cache=True, error_model="numpy", inline="always")
def cross_features_step(
    step_e: float, step_n: float, period: float, speed: float, heading: float, out: FloatArray
) -> None:
    """Implied-vs-reported speed (m/s) and course (degrees) from the last step."""
    implied = np.hypot(step_e, step_n) / period
    out[0] = implied - speed
    gap = np.nan
    if implied >= MIN_COURSE_SPEED and np.isfinite(heading):
        course = np.degrees(np.arctan2(step_e, step_n))
        gap = (course - heading + 180.0) % 360.0 - 180.0
    out[1] = gap


@numba.njit(cache=True, error_model="numpy")
def features_batch_kernel(
    east: FloatArray,
    north: FloatArray,
    speed: FloatArray,
    heading: FloatArray,
    period: float,
    long_n: int,
    short_n: int,
    rema_p: FloatArray,
    cross: bool,
) -> FloatArray:
    n = east.size
    width = 2 * N_CHANNEL + (2 if cross else 0)
    out = np.empty((n, width))
    step_e = np.empty(n)
    step_n = np.empty(n)
    for i in range(n):
        step_e[i], step_n[i] = velocity_step(speed[i], heading[i], period)
    rema_e = rema_batch_kernel(rema_p, east, step_e)
    rema_n = rema_batch_kernel(rema_p, north, step_n)
    size = 2 * max(long_n, short_n + 1)
    hist_e = np.zeros(size)
    hist_n = np.zeros(size)
    for i in range(n):
        win_e = history_push(hist_e, i + 1, east[i])
        win_n = history_push(hist_n, i + 1, north[i])
        channel_features_step(win_e, long_n, short_n, period, rema_e[i], out[i, :N_CHANNEL])
        channel_features_step(
            win_n, long_n, short_n, period, rema_n[i], out[i, N_CHANNEL : 2 * N_CHANNEL]
        )
        if cross:
            if i == 0:
                out[i, 2 * N_CHANNEL] = np.nan
                out[i, 2 * N_CHANNEL + 1] = np.nan
            else:
                cross_features_step(
                    east[i] - east[i - 1],
                    north[i] - north[i - 1],
                    period,
                    speed[i],
                    heading[i],
                    out[i, 2 * N_CHANNEL :],
                )
    return out


def _segment_period(t: FloatArray) -> float:
    if t.size < 2:
        return 1.0
    return float(np.median(np.diff(t)))


def _optional(values: ArrayLike | None, n: int, name: str) -> FloatArray:
    if values is None:
        return np.full(n, np.nan)
    arr = np.ascontiguousarray(values, dtype=np.float64)
    if arr.shape != (n,):
        raise ConfigError(f"{name} must have one value per point ({n}), got shape {arr.shape}")
    return arr


def segment_features(
    t: ArrayLike,
    east: ArrayLike,
    north: ArrayLike,
    params: FeatureParams | None = None,
    rema_params: RemaParams | None = None,
    *,
    speed: ArrayLike | None = None,
    heading: ArrayLike | None = None,
) -> FloatArray:
    """MS-SW + REMA features of one preprocessed segment: ``(n, len(feature_names(params)))``.

    ``t`` seconds (evenly spaced, increasing; its median step is the period),
    ``east``/``north`` metres, optional ``speed`` m/s and ``heading`` degrees.
    """
    prm = params or FeatureParams()
    t_a = np.ascontiguousarray(t, dtype=np.float64)
    e = np.ascontiguousarray(east, dtype=np.float64)
    nn = np.ascontiguousarray(north, dtype=np.float64)
    if not (t_a.shape == e.shape == nn.shape) or t_a.ndim != 1:
        raise ConfigError(
            f"t, east, north must be 1-D of one length, got {t_a.shape}, {e.shape}, {nn.shape}"
        )
    period = _segment_period(t_a)
    long_n, short_n = prm.points(period)
    sp = _optional(speed, e.size, "speed")
    hd = _optional(heading, e.size, "heading")
    rema_p = (rema_params or RemaParams()).to_array()
    return features_batch_kernel(e, nn, sp, hd, period, long_n, short_n, rema_p, prm.speed_heading)


def _channel_reference(
    x: FloatArray, period: float, long_n: int, short_n: int, rema_rows: FloatArray
) -> FloatArray:
    """Readable per-point features of one channel with NumPy on explicit windows."""
    n = x.size
    out = np.zeros((n, N_CHANNEL))
    for i in range(n):
        win = x[max(0, i - long_n + 1) : i + 1] - x[i]
        tt = np.arange(win.size) * period
        if win.size >= 2:
            slope, intercept = np.polyfit(tt, win, 1)
            fitted = intercept + slope * tt
            out[i, 0] = slope
            out[i, 1] = fitted[-1]
            if win.size > 2:
                out[i, 2] = np.sqrt(np.sum((win - fitted) ** 2) / (win.size - 2))
        short = x[max(0, i - short_n) : i + 1]
        steps = np.diff(short)
        if steps.size:
            out[i, 3] = np.std(steps / period)
            gain, loss = steps[steps > 0].sum(), -steps[steps < 0].sum()
            out[i, 4] = 100.0 * gain / (gain + loss) if gain + loss > 0 else 50.0
            out[i, 6] = steps[-1] / period
        else:
            out[i, 4] = 50.0
        out[i, 5] = short.max() - short.min()
    width = rema_rows[:, O_UPPER] - rema_rows[:, O_LOWER]
    out[:, 7] = rema_rows[:, O_DISTANCE]
    out[:, 8] = np.where(np.isfinite(width), width, 0.0)
    out[:, 9] = rema_rows[:, O_FLAG]
    out[:, 10] = rema_rows[:, O_ALPHA]
    return out


def features_reference(
    t: ArrayLike,
    east: ArrayLike,
    north: ArrayLike,
    params: FeatureParams | None = None,
    rema_params: RemaParams | None = None,
    *,
    speed: ArrayLike | None = None,
    heading: ArrayLike | None = None,
) -> FloatArray:
    """Readable NumPy version of :func:`segment_features` (np.polyfit per window), for tests."""
    prm = params or FeatureParams()
    t_a = np.asarray(t, dtype=np.float64)
    e = np.asarray(east, dtype=np.float64)
    nn = np.asarray(north, dtype=np.float64)
    period = _segment_period(t_a)
    long_n, short_n = prm.points(period)
    rp = (rema_params or RemaParams()).to_array()
    step_e, step_n = velocity_steps(speed, heading, period, e.size)
    parts = [
        _channel_reference(e, period, long_n, short_n, rema_batch_kernel(rp, e, step_e)),
        _channel_reference(nn, period, long_n, short_n, rema_batch_kernel(rp, nn, step_n)),
    ]
    if prm.speed_heading:
        sp = _optional(speed, e.size, "speed")
        hd = _optional(heading, e.size, "heading")
        cross = np.full((e.size, 2), np.nan)
        de, dn = np.diff(e), np.diff(nn)
        implied = np.hypot(de, dn) / period
        cross[1:, 0] = implied - sp[1:]
        course = np.degrees(np.arctan2(de, dn))
        gap = (course - hd[1:] + 180.0) % 360.0 - 180.0
        cross[1:, 1] = np.where((implied >= MIN_COURSE_SPEED) & np.isfinite(hd[1:]), gap, np.nan)
        parts.append(cross)
    return np.hstack(parts)

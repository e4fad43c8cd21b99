"""Honest inputs: say when a file is outside what the model was validated on.

A detector trained and validated on 0.5-10 Hz drives still answers on a
0.1 Hz log, on a file whose timestamps repeat, or on one whose positions
imply jet speeds; its answer there is not backed by any measurement. Rather
than silently flag such a file, the tools say so, once, with the numbers.

:class:`InputChecks` gathers the facts from canonical fixes (one table, or
chunk after chunk of a big file, with bounded memory) and :meth:`warnings`
turns them into one sentence per problem; :func:`input_warnings` does both
for one table. Definitions, per track, over valid fixes (finite time,
latitude within +-90, longitude within +-180) in time order:

* a *step* is the time from one fix to the next; steps shorter than
  :data:`REPEAT_S` (1 ms, what the detector treats as one instant) are
  *repeated timestamps*, the others *proper steps*;
* the median and quartiles are those of the proper steps of all tracks,
  read from a histogram with bins 1.2 % wide (so a file read in chunks gets
  the same numbers as the whole file);
* the *implied speed* of a proper step is the great-circle distance between
  its fixes over its duration.

Warnings (thresholds are module constants):

* ``slow rate``: median step above ``1 / min_rate_hz`` (the slowest rate the
  model was validated on; 2 s by default);
* ``fast rate``: median step below ``1 / max_rate_hz``;
* ``repeated timestamps``: more than 1 % of steps repeat a timestamp;
* ``implausible speeds``: more than :data:`MAX_FAST_STEPS` steps, and more
  than :data:`MAX_FAST_SHARE` of all proper steps, imply more than 100 m/s.
  The share keeps files *with faults* quiet: faults are what the detector is
  for, and protocol ``grad`` faults (20-200 m jumps, 10-50 m noise) make 3 %
  (DrivePlotR, 1 Hz) to 13 % (TUC, 4-5 Hz) of steps that fast, where the
  clean real drives have 0-3 such steps each; a misread time unit or
  coordinate column makes nearly all of them that fast;
* ``irregular sampling``: the proper steps' interquartile range is more than
  half their median;
* ``noisy fixes``: the median *second difference* of the positions (over three
  fixes with steps within 10 % of each other: where the third fix lands beyond
  the line the first two draw, in metres) is above :data:`NOISY_SECOND_DIFF_M`
  over at least :data:`MIN_TRIPLES` such triples. A car's driving moves it by
  centimetres to a metre there; a receiver's noise by more. Every real drive
  the shipped model was trained and validated on has a median of at most 1.35 m
  (the Nevada Garmin's train drive at 0.5 Hz; DrivePlotR 0.64 m, the NL
  motorway phones and logger 0.39-0.44 m, Austin 1.1 m; TUC's smoothed ground
  truth 0.01 m), the simulator's logger 0.58 m at 1 Hz; on simulated receivers with a median of 2.1 m the
  shipped model flagged 0.35-0.41 % of clean fixes, with 6.0 m 2-9 %, with
  12.2 m 9-51 % (``benchmarks/tried/receiver_noise_levels.py``,
  ``benchmarks/tried/receiver_noise_check.py``): its answers on such files are
  not backed by any measurement on real data.

A small tolerance (:data:`RATE_TOLERANCE`) keeps a file recorded exactly at
the validated limit (0.5 Hz) from being warned about.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any

import numpy as np
import pandas as pd

from .geo import EARTH_MEAN_RADIUS_M, haversine_m

__all__ = [
    "IRREGULAR_IQR_RATIO",
    "MAX_FAST_SHARE",
    "MAX_FAST_STEPS",
    "MAX_REPEAT_SHARE",
    "MAX_SPEED_MPS",
    "MIN_TRIPLES",
    "NOISY_SECOND_DIFF_M",
    "RATE_TOLERANCE",
    "REPEAT_S",
    "VALIDATED_DEFAULT",
    "InputChecks",
    "input_warnings",
    "validated_rates",
]

#: Rates the model was validated on when its config.json has no ``validated`` block.
VALIDATED_DEFAULT = {"min_rate_hz": 0.5, "max_rate_hz": 10.0}
#: Steps shorter than this are repeated timestamps (the detector's shortest step).
REPEAT_S = 1e-3
MAX_REPEAT_SHARE = 0.01
MAX_SPEED_MPS = 100.0
#: "More than a few": isolated real glitches (a cold start, a tunnel exit) are
#: what the detector is for; more than this many suggest wrong units or columns.
MAX_FAST_STEPS = 5
#: ... and more than this share of the proper steps (see the module docstring).
MAX_FAST_SHARE = 0.2
IRREGULAR_IQR_RATIO = 0.5
#: m: a median second difference of the positions above this is a noisy receiver
#: (see the module docstring: at most 1.35 m on the real drives the model knows).
NOISY_SECOND_DIFF_M = 3.0
#: Second differences needed before the median says anything.
MIN_TRIPLES = 50
#: Steps of a triple whose durations differ by more than this share are not used.
_TRIPLE_TOLERANCE = 0.1
#: Relative slack on the rate limits (histogram resolution and clock jitter).
RATE_TOLERANCE = 0.05

# Histogram of proper steps: bin k holds steps with round(BINS_PER_DECADE * log10(dt)) == k.
_BINS_PER_DECADE = 200
_K_MIN = round(_BINS_PER_DECADE * math.log10(REPEAT_S))
_K_MAX = _BINS_PER_DECADE * 9  # 1e9 s: anything longer lands in the last bin
# Histogram of second differences (m): bin j holds round(_BINS_PER_DECADE * log10(d)) == j,
# from 1 mm (and below) to 100 km (and above).
_J_MIN = -3 * _BINS_PER_DECADE
_J_MAX = 5 * _BINS_PER_DECADE


def _log_quantile(hist: np.ndarray, first_bin: int, q: float) -> float:
    """The ``q`` quantile of a histogram whose bin ``k`` holds values with
    ``round(_BINS_PER_DECADE * log10(value)) == k + first_bin`` (the bin's centre); nan
    if it is empty."""
    n = int(hist.sum())
    if n == 0:
        return float("nan")
    k = int(np.searchsorted(np.cumsum(hist), max(1, math.ceil(q * n))))
    return float(10.0 ** ((k + first_bin) / _BINS_PER_DECADE))


def validated_rates(config: Mapping[str, Any] | None) -> tuple[float, float]:
    """``(min_rate_hz, max_rate_hz)`` from a model config's ``validated`` block, else the defaults."""
    block = (config or {}).get("validated")
    block = block if isinstance(block, Mapping) else {}
    lo = block.get("min_rate_hz", VALIDATED_DEFAULT["min_rate_hz"])
    hi = block.get("max_rate_hz", VALIDATED_DEFAULT["max_rate_hz"])
    return float(lo), float(hi)


class InputChecks:
    """Facts about fixes for :meth:`warnings`, fed one table or chunk at a time with :meth:`add`.

    Memory is a fixed histogram plus the last fix of each track. Fixes of a
    track are taken in time order within each table; across tables (chunks
    of one file) a fix not after its track's last one starts no step.
    """

    def __init__(
        self,
        min_rate_hz: float = VALIDATED_DEFAULT["min_rate_hz"],
        max_rate_hz: float = VALIDATED_DEFAULT["max_rate_hz"],
    ) -> None:
        self.min_rate_hz = float(min_rate_hz)
        self.max_rate_hz = float(max_rate_hz)
        self.hist = np.zeros(_K_MAX - _K_MIN + 1, dtype=np.int64)
        self.repeats = 0
        self.fast = 0
        self.fastest = 0.0
        self.second_diff_hist = np.zeros(_J_MAX - _J_MIN + 1, dtype=np.int64)
        # The last two fixes of each track (t, lat, lon), oldest first.
        self._last: dict[str, list[tuple[float, float, float]]] = {}
        #: What the reader assumed about the columns (``fixes.attrs["notes"]``), once each.
        self.notes: list[str] = []

    def add(self, fixes: pd.DataFrame) -> InputChecks:
        """Take in canonical fixes (columns ``track``, ``t``, ``lat``, ``lon``); returns ``self``."""
        for note in fixes.attrs.get("notes", ()):
            if note not in self.notes:
                self.notes.append(note)
        t = fixes["t"].to_numpy(dtype=np.float64)
        lat = fixes["lat"].to_numpy(dtype=np.float64)
        lon = fixes["lon"].to_numpy(dtype=np.float64)
        with np.errstate(invalid="ignore"):
            valid = (
                np.isfinite(t)
                & np.isfinite(lat)
                & np.isfinite(lon)
                & (np.abs(lat) <= 90.0)
                & (np.abs(lon) <= 180.0)
            )
        frame = pd.DataFrame(
            {
                "track": fixes["track"].astype(str).to_numpy(dtype=object)[valid],
                "t": t[valid],
                "lat": lat[valid],
                "lon": lon[valid],
            }
        ).sort_values(["track", "t"], kind="stable")
        for name, part in frame.groupby("track", sort=False):
            tt = part["t"].to_numpy()
            la = part["lat"].to_numpy()
            lo = part["lon"].to_numpy()
            last = self._last.get(str(name), [])
            if last and tt[0] >= last[-1][0]:
                # The track goes on: its last fixes (in time order) lead this chunk's;
                # their own step was counted with the chunk before.
                tt = np.r_[[f[0] for f in last], tt]
                la = np.r_[[f[1] for f in last], la]
                lo = np.r_[[f[2] for f in last], lo]
                self._steps(tt[len(last) - 1 :], la[len(last) - 1 :], lo[len(last) - 1 :])
            else:
                self._steps(tt, la, lo)
            self._second_differences(tt, la, lo)
            self._last[str(name)] = [
                (float(a), float(b), float(c))
                for a, b, c in zip(tt[-2:], la[-2:], lo[-2:], strict=True)
            ]
        return self

    def _second_differences(self, t: np.ndarray, lat: np.ndarray, lon: np.ndarray) -> None:
        """Histogram where each fix lands beyond the line its two predecessors draw (m), over
        triples whose two steps are proper and within 10 % of each other."""
        if t.size < 3:
            return
        dt = np.diff(t)
        d1, d2 = dt[:-1], dt[1:]
        with np.errstate(divide="ignore", invalid="ignore"):
            even = (d1 >= REPEAT_S) & (d2 >= REPEAT_S) & (np.abs(d2 - d1) <= _TRIPLE_TOLERANCE * d1)
        if not even.any():
            return
        i = np.flatnonzero(even)
        per_deg = math.radians(1.0) * EARTH_MEAN_RADIUS_M
        scale = np.cos(np.radians(lat[i + 1])) * per_deg
        east01 = ((lon[i + 1] - lon[i] + 540.0) % 360.0 - 180.0) * scale  # across +-180 too
        east12 = ((lon[i + 2] - lon[i + 1] + 540.0) % 360.0 - 180.0) * scale
        ratio = d2[i] / d1[i]
        # The third fix against the first two's straight-line extrapolation over its step.
        de = east12 - east01 * ratio
        dn = ((lat[i + 2] - lat[i + 1]) - (lat[i + 1] - lat[i]) * ratio) * per_deg
        size = np.hypot(de, dn)
        with np.errstate(divide="ignore"):
            j = np.rint(_BINS_PER_DECADE * np.log10(np.maximum(size, 1e-9)))
        j = np.clip(j.astype(np.int64), _J_MIN, _J_MAX)
        self.second_diff_hist += np.bincount(j - _J_MIN, minlength=self.second_diff_hist.size)

    def second_difference_median(self) -> float:
        """Median second difference of the positions in metres (bin centre); nan if none."""
        return _log_quantile(self.second_diff_hist, _J_MIN, 0.5)

    def _steps(self, t: np.ndarray, lat: np.ndarray, lon: np.ndarray) -> None:
        dt = np.diff(t)
        if dt.size == 0:
            return
        proper = dt >= REPEAT_S
        self.repeats += int((~proper).sum())
        d = dt[proper]
        k = np.clip(np.rint(_BINS_PER_DECADE * np.log10(d)).astype(np.int64), _K_MIN, _K_MAX)
        self.hist += np.bincount(k - _K_MIN, minlength=self.hist.size)
        dist = haversine_m(lat[:-1][proper], lon[:-1][proper], lat[1:][proper], lon[1:][proper])
        speed = dist / d
        fast = speed > MAX_SPEED_MPS
        self.fast += int(fast.sum())
        if fast.any():
            self.fastest = max(self.fastest, float(speed[fast].max()))

    @property
    def steps(self) -> int:
        """All steps seen: proper ones and repeated timestamps."""
        return int(self.hist.sum()) + self.repeats

    def step_quantile(self, q: float) -> float:
        """The ``q`` quantile of the proper steps in seconds (histogram bin centre); nan if none."""
        return _log_quantile(self.hist, _K_MIN, q)

    def warnings(self) -> list[str]:
        """One sentence per way the input is outside what the model was validated on."""
        out: list[str] = list(self.notes)
        if self.steps == 0:
            return out
        median = self.step_quantile(0.5)
        slowest = 1.0 / self.min_rate_hz
        fastest = 1.0 / self.max_rate_hz
        if math.isfinite(median) and median > slowest * (1.0 + RATE_TOLERANCE):
            out.append(
                f"median time step {median:.2g} s ({1.0 / median:.2g} Hz) is slower than the "
                f"slowest rate the model was validated on ({self.min_rate_hz:g} Hz, one fix every "
                f"{slowest:g} s): expect more false alarms and missed faults"
            )
        if math.isfinite(median) and median < fastest / (1.0 + RATE_TOLERANCE):
            out.append(
                f"median time step {median:.2g} s ({1.0 / median:.2g} Hz) is faster than the "
                f"fastest rate the model was validated on ({self.max_rate_hz:g} Hz): results "
                "there are not measured"
            )
        if self.repeats > MAX_REPEAT_SHARE * self.steps:
            out.append(
                f"{self.repeats:,} of {self.steps:,} time steps "
                f"({100.0 * self.repeats / self.steps:.1f} %) repeat the previous fix's timestamp "
                "(within 1 ms): check the time column's resolution; repeated fixes are merged "
                "(whole file) or flagged invalid (chunks, --follow)"
            )
        proper = int(self.hist.sum())
        if self.fast > MAX_FAST_STEPS and self.fast > MAX_FAST_SHARE * proper:
            out.append(
                f"{self.fast:,} of {proper:,} time steps ({100.0 * self.fast / proper:.0f} %) "
                f"imply speeds above {MAX_SPEED_MPS:g} m/s (fastest {self.fastest:,.0f} m/s): "
                "check the time unit and the latitude/longitude columns; so many are not "
                "glitches of a car's receiver"
            )
        triples = int(self.second_diff_hist.sum())
        noise = self.second_difference_median()
        if triples >= MIN_TRIPLES and noise > NOISY_SECOND_DIFF_M:
            out.append(
                f"noisy fixes: the median fix lands {noise:.2g} m off the line its two "
                "predecessors draw (at most 1.4 m on every real drive the model was "
                "trained and validated on): a noisier receiver than the model has been "
                "measured on; expect false alarms on its ordinary noise"
            )
        q1, q3 = self.step_quantile(0.25), self.step_quantile(0.75)
        if math.isfinite(median) and q3 - q1 > IRREGULAR_IQR_RATIO * median:
            out.append(
                f"irregular sampling: time steps between {q1:.2g} s and {q3:.2g} s (quartiles) "
                f"around a median of {median:.2g} s; the model was validated on evenly "
                "sampled drives"
            )
        return out


def input_warnings(
    fixes: pd.DataFrame,
    *,
    min_rate_hz: float = VALIDATED_DEFAULT["min_rate_hz"],
    max_rate_hz: float = VALIDATED_DEFAULT["max_rate_hz"],
) -> list[str]:
    """The warnings of :class:`InputChecks` for one canonical fixes frame."""
    return InputChecks(min_rate_hz, max_rate_hz).add(fixes).warnings()

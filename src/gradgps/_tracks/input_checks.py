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
  half their median.

A small tolerance (:data:`RATE_TOLERANCE`) keeps a file recorded exactly at
the validated limit (0.5 Hz) from being warned about.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any

import numpy as np
import pandas as pd

from .geo import haversine_m

__all__ = [
    "IRREGULAR_IQR_RATIO",
    "MAX_FAST_SHARE",
    "MAX_FAST_STEPS",
    "MAX_REPEAT_SHARE",
    "MAX_SPEED_MPS",
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
#: Relative slack on the rate limits (histogram resolution and clock jitter).
RATE_TOLERANCE = 0.05

# Histogram of proper steps: bin k holds steps with round(BINS_PER_DECADE * log10(dt)) == k.
_BINS_PER_DECADE = 200
_K_MIN = round(_BINS_PER_DECADE * math.log10(REPEAT_S))
_K_MAX = _BINS_PER_DECADE * 9  # 1e9 s: anything longer lands in the last bin


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
        self._last: dict[str, tuple[float, float, float]] = {}
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
            last = self._last.get(str(name))
            if last is not None and tt[0] >= last[0]:
                tt, la, lo = np.r_[last[0], tt], np.r_[last[1], la], np.r_[last[2], lo]
            self._last[str(name)] = (float(tt[-1]), float(la[-1]), float(lo[-1]))
            self._steps(tt, la, lo)
        return self

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
        n = int(self.hist.sum())
        if n == 0:
            return float("nan")
        k = int(np.searchsorted(np.cumsum(self.hist), max(1, math.ceil(q * n))))
        return float(10.0 ** ((k + _K_MIN) / _BINS_PER_DECADE))

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

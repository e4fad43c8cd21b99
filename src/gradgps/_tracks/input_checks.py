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
* ``repeated timestamps``: more than 1 % of steps repeat a timestamp, or any
  repeats one at a new position (a distinct fix in the same instant: the
  time column is coarser than the fixes come). No real drive of
  ``../shared/data`` has one; written to whole seconds of a clock on which
  the 1 Hz fixes come 0.995 s apart (one repeated second every 200 s, 0.5 %
  of the steps) the clean NL motorway validation drives had 47 % of their fixes
  flagged, with no word (``benchmarks/time_columns.py``): the step after each
  repeat covers two fixes' motion in one second, a jump the offset tracker
  held. The detector now begins a new segment there
  (:func:`gradgps._tracks.preprocess.time_glitch_breaks`): 2.4 %, the repeats
  themselves (invalid) included;
* ``implausible speeds``: more than :data:`MAX_FAST_STEPS` steps, and more
  than :data:`MAX_FAST_SHARE` of all proper steps, imply more than 100 m/s.
  The share keeps files *with faults* quiet: faults are what the detector is
  for, and protocol ``grad`` faults (20-200 m jumps, 10-50 m noise) make 3 %
  (DrivePlotR, 1 Hz) to 13 % (TUC, 4-5 Hz) of steps that fast, where the
  clean real drives have 0-3 such steps each; a misread time unit or
  coordinate column makes nearly all of them that fast;
* ``irregular sampling``: the proper steps' interquartile range is more than
  half their median;
* ``repeated fixes``: the positions change less often than the fixes come:
  the lower quartile of the time between *position updates* (fixes whose
  latitude or longitude differs from the fix before, over proper steps) is at
  least :data:`PADDED_RATIO` times the upper quartile of the steps, over at
  least :data:`MIN_UPDATES` updates (quartiles, not medians: a drive that lost
  half its fixes at random has half its steps one period long, and its medians
  of steps and of updates fall either side of that by a count or two). A
  receiver's fixes re-sampled onto a faster clock (a data logger or vehicle bus
  that samples the last fix at 5-10 Hz, a topic republished faster than the
  receiver solves) look so: each new fix is followed by exact copies of
  itself. The detector reads every row as a new fix, so the car seems to stand
  still and then leap, and on the real validation drives re-sampled so (every
  fix repeated 2, 5 or 10 times) the shipped model flagged 0.5-38 % of clean
  fixes (``benchmarks/padded_streams.py``). An ordinary drive's stops do not
  make it: while the car moves the position changes at every fix, and a stop
  adds one long interval between updates, not many (every real drive of
  ``../shared/data``, every split, at its own rate and decimated to 0.5 Hz:
  ratio 1 or less). Where it is found, ``noisy fixes`` is not said: the
  triples behind it then measure the leaps, not the receiver's noise;
* ``coarse coordinates``: at least :data:`COARSE_SHARE` of the fixes (and at
  least :data:`MIN_TRIPLES`) have a latitude and longitude on one grid of
  :data:`COARSE_GRIDS_DEG` (4 decimals of a degree or fewer, or whole hundredths
  or tenths of a minute): each fix is then rounded by up to half a cell, 5.6 m
  or more north-south, where the model was trained on fixes to a metre or
  better. On the real validation drives rounded to 4 decimals the shipped model
  flagged 2.0-9.8 % of clean fixes, to hundredths of a minute 4.2-27.0 %, at 5
  decimals or thousandths of a minute what it flags unrounded
  (``benchmarks/coarse_coordinates.py``). Full-precision coordinates land on
  such a grid by chance about once in a million. Where it is found, ``repeated
  fixes`` and ``noisy fixes`` are not said: the rounding makes both;
* ``time runs backwards``: at least :data:`MIN_TRIPLES` valid fixes, and a
  quarter of them, come (in file order) before a fix above them in their
  track. Each track is read in row order and such a fix is flagged invalid
  (``invalid_reason``), so a file written newest first had every fix but its
  first flagged, with no word on why;
* ``one-fix tracks``: at least half of the fixes (and at least
  :data:`MIN_TRIPLES`) are alone in their track. The detector judges a fix
  against the fixes before it in its track, so it flags none of them: a file
  whose ``id`` column numbers the rows (a database export, a point id) is
  read as one track per row, and would otherwise be passed as clean whatever
  it holds;
* ``noisy fixes``: the lower quartile of the *second differences* of the
  positions (over three fixes with steps within 10 % of each other: where the
  third fix lands beyond the line the first two draw, in metres; exact repeats,
  a receiver pinning a standing car, left out) is above
  :data:`NOISY_QUARTILE_M` over at least :data:`MIN_TRIPLES` such triples. A
  car's driving moves it by centimetres to a metre there; a receiver's noise by
  more. The quartile, not the median: a fault moves the three triples around
  it by tens of metres, and protocol ``grad`` (a tenth of the fixes) put the
  median of clean loggers at 0.5 Hz above 3 m (Austin's training drives 3.39 m,
  from 2.29 m clean), while their quartile stays at most 1.68 m. Every real
  drive the shipped model was trained and validated on has a quartile of at
  most 0.87 m at its own rate (Austin's training drives; DrivePlotR 0.43-0.62 m,
  the NL motorway phones and logger 0.23-0.35 m, the Nevada Garmin 0.23-0.47 m,
  TUC's smoothed ground truth 0.01 m) and 1.30 m decimated to 0.5 Hz; the
  simulator's logger 0.42 m at 1 Hz. For independent errors the quartile is
  0.74 of the median (the simulated receivers below), so 2.2 m is the median of
  3 m the check used before. Simulated receivers (their median, quartile at
  1 Hz): 2.09 / 1.55 m, where the shipped model flagged 0.35-0.41 % of clean
  fixes; 5.96 / 4.42 m, 2-9 %; 12.16 / 9.02 m, 9-51 %
  (``benchmarks/tried/receiver_noise_levels.py``,
  ``benchmarks/tried/receiver_noise_check.py``): its answers on such files are
  not backed by any measurement on real data.
* ``interleaved sources``: consecutive fixes zig-zag while every other fix
  keeps to a smooth path: the median *second difference* over consecutive
  fixes (as for ``noisy fixes``, but over steps up to
  :data:`INTERLEAVE_STEP_RATIO` times each other, so that two 1 Hz receivers
  a third of a second apart count too) is at least :data:`INTERLEAVED_RATIO`
  times the median over every other fix (fixes ``i``, ``i + 2``, ``i + 4``),
  and at least :data:`INTERLEAVED_MIN_M`, over at least :data:`MIN_TRIPLES`
  of each (exact repeats left out). A driven path bends more over two steps
  than over one (four times as much at a steady turn), and a receiver's
  independent noise is the same over both, so an ordinary drive's ratio is
  about 1 or less; two receivers (or vehicles) merged into one track with
  their fixes alternating put every consecutive triple across the gap between
  them and every other fix on one of them. A file that merges fleet devices
  without a track column does this; merged half a second apart, the NL
  motorway receivers had 9-46 % of their clean fixes flagged with no word
  (``benchmarks/merged_receivers.py``). Where it is found, ``noisy fixes`` and
  ``irregular sampling`` are not said: the zig-zag makes the one, the two
  clocks the other;
* ``reported speed`` / ``reported heading``: a speed or heading column that
  contradicts the positions. Each is held against the *chords*: the steps
  between the first fixes of each second of a track (:data:`WITNESS_BASELINE_S`),
  at most 5 s and at least 5 m long, driven at 5-100 m/s (by the chord and by the
  reported speed). A step's speed agrees within 15 % of its chord's, its heading
  within 15 degrees of its chord's bearing; a witness that agrees on fewer than a
  third of at least 50 such steps is named, with the unit or convention it fits
  (km/h, mph or knots read as m/s; radians; degrees counter-clockwise from east).
  A speed column that reads under :data:`STILL_SPEED_MPS` on at least half of
  at least 50 steps the positions drive at 5-100 m/s is named too (a
  placeholder an export fills with zeros, not a measurement: such steps are
  left out of the agreement above, which then has nothing to go on); written
  so on the clean validation drives that have a speed, the shipped model
  flagged 0.00 / 0.50 / 4.15 % of TUC's, DrivePlotR's and Nevada's fixes, with
  no warning before (``benchmarks/placeholder_speed.py``).
  On every real drive of ``../shared/data`` with a speed or heading 94-100 % of
  the steps agree, and 64-89 % with protocol ``grad`` or ``gnss`` faults
  injected (``benchmarks/witness_agreement.py``): faults make their own steps
  disagree, not the clean ones. A speed in
  km/h read as m/s made the shipped model flag 34.3 % of a clean 0.5 Hz drive's
  fixes (``benchmarks/witness_units.py``).

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
from .track import SPEED_UNITS

__all__ = [
    "CHECK_EVERY",
    "COARSE_GRIDS_DEG",
    "COARSE_SHARE",
    "INTERLEAVED_MIN_M",
    "INTERLEAVED_RATIO",
    "INTERLEAVE_STEP_RATIO",
    "IRREGULAR_IQR_RATIO",
    "MAX_FAST_SHARE",
    "MAX_FAST_STEPS",
    "MAX_REPEAT_SHARE",
    "MAX_SPEED_MPS",
    "MIN_TRIPLES",
    "MIN_UPDATES",
    "NOISY_QUARTILE_M",
    "PADDED_RATIO",
    "RATE_TOLERANCE",
    "REPEAT_S",
    "STILL_SPEED_MPS",
    "VALIDATED_DEFAULT",
    "InputChecks",
    "input_warnings",
    "validated_rates",
]

#: Scored fixes before the first look of the input checks on a stream (follow mode, the
#: Redis worker; ten minutes at 1 Hz: the checks need a few hundred steps to say
#: anything); each later look waits twice as many fixes as the one before, so a day-long
#: stream pays for a dozen looks of a few milliseconds.
CHECK_EVERY = 600

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
#: m: a lower quartile of the second differences of the positions above this is a noisy
#: receiver (see the module docstring: at most 1.30 m on the real drives the model knows,
#: 1.68 m with faults injected).
NOISY_QUARTILE_M = 2.2
#: Second differences needed before the median says anything.
MIN_TRIPLES = 50
#: Positions that change at most once in this many median steps are fixes re-sampled
#: onto a faster clock (see the module docstring: 1 on every real drive we hold; a 1 Hz
#: receiver logged at 2 Hz gives 2) ...
PADDED_RATIO = 1.8
#: ... over at least this many position updates.
MIN_UPDATES = 50
#: Grids (degrees, coarsest first) a coordinate column may be rounded to, with their
#: names: cells of 5 m or more north-south (a degree of latitude is 111.2 km).
COARSE_GRIDS_DEG = (
    (1e-2, "2 decimals of a degree"),
    (1.0 / 600.0, "tenths of a minute"),
    (1e-3, "3 decimals of a degree"),
    (1.0 / 6000.0, "hundredths of a minute"),
    (1e-4, "4 decimals of a degree"),
)
#: Share of the fixes on one grid that makes the file's coordinates that coarse.
COARSE_SHARE = 0.99
#: A value is on a grid when it is within this share of a cell of a grid line (the
#: decimal text of a rounded value, parsed, lands within 1e-10 of a cell).
_GRID_TOLERANCE = 1e-6
#: Steps of a triple whose durations differ by more than this share are not used.
_TRIPLE_TOLERANCE = 0.1
#: Two sources interleaved in one track: the median second difference over consecutive
#: fixes at least this many times the median over every other fix (an ordinary drive's
#: is about 1 or less: see ``interleaved sources``) ...
INTERLEAVED_RATIO = 3.0
#: ... and at least this many metres (a zig-zag within a good receiver's noise says nothing).
INTERLEAVED_MIN_M = 1.0
#: Triples of that comparison: the longer of their two steps at most this many times the
#: shorter (two 1 Hz receivers 0.3-0.7 s apart; further apart, ``irregular sampling``).
INTERLEAVE_STEP_RATIO = 2.5
#: Relative slack on the rate limits (histogram resolution and clock jitter).
RATE_TOLERANCE = 0.05
#: A reported speed or heading is held against the step between two fixes (the chord),
#: fixes taken at most one per this many seconds of the track's time ...
WITNESS_BASELINE_S = 1.0
#: ... and only where the chord says something about it: steps of at most this many
#: seconds ...
WITNESS_MAX_STEP_S = 5.0
#: ... covering at least this many metres (a receiver's metre of noise is then a fifth of
#: the chord at most, and a median over many steps is off by far less) ...
WITNESS_MIN_CHORD_M = 5.0
#: ... at a speed between this (m/s: moving, by the chord and by the reported speed where
#: the fixes have one) and :data:`MAX_SPEED_MPS` (not a glitch).
WITNESS_MIN_SPEED_MPS = 5.0
#: Such steps needed before the comparison says anything.
MIN_WITNESS_STEPS = 50
#: m/s: a reported speed below this on a step the positions drive at
#: :data:`WITNESS_MIN_SPEED_MPS` or more says the car stands while it moves.
STILL_SPEED_MPS = 0.5
#: A reported speed agrees with a step when its ratio to the chord's speed is within
#: this factor of 1 (a receiver's Doppler speed and its chords agree within a few per
#: cent; a unit mix-up is a factor of 1.85, knots for km/h, or more) ...
SPEED_AGREEMENT = 1.15
#: ... and a reported heading when it is within this many degrees of the chord's bearing.
HEADING_AGREEMENT_DEG = 15.0
#: A witness that agrees with fewer than this share of its steps contradicts the
#: positions. Faults do not make it: their steps disagree at random, and the clean steps
#: still agree (more than half of the steps of every real drive of ``../shared/data``
#: with faults injected, ``tests/test_input_checks.py``), where a wrong unit or
#: convention leaves only the chance agreements of a few per cent.
MIN_AGREEMENT = 1.0 / 3.0
#: Relative slack when naming the unit mix-up a speed ratio matches (the mix-ups of one
#: reading unit are 15 % apart or more).
SPEED_UNIT_TOLERANCE = 0.05

# Histogram of proper steps: bin k holds steps with round(BINS_PER_DECADE * log10(dt)) == k.
_BINS_PER_DECADE = 200
_K_MIN = round(_BINS_PER_DECADE * math.log10(REPEAT_S))
_K_MAX = _BINS_PER_DECADE * 9  # 1e9 s: anything longer lands in the last bin
# Histogram of second differences (m): bin j holds round(_BINS_PER_DECADE * log10(d)) == j,
# from 1 mm (and below) to 100 km (and above).
_J_MIN = -3 * _BINS_PER_DECADE
_J_MAX = 5 * _BINS_PER_DECADE
# Histogram of reported speed over chord speed: bin r holds round(_BINS_PER_DECADE *
# log10(ratio)) == r, from 1/1000 (and below, a reported 0 too) to 1000 (and above).
_R_MIN = -3 * _BINS_PER_DECADE
_R_MAX = 3 * _BINS_PER_DECADE
#: Readings of a heading column tried against the chords, in this order: as the model
#: reads it (degrees clockwise from north), as radians, as degrees counter-clockwise from
#: east (mathematics' convention).
HEADING_READINGS = ("degrees", "radians", "counter-clockwise from east")


def _log_quantile(hist: np.ndarray, first_bin: int, q: float) -> float:
    """The ``q`` quantile of a histogram whose bin ``k`` holds values with
    ``round(_BINS_PER_DECADE * log10(value)) == k + first_bin`` (the bin's centre); nan
    if it is empty."""
    n = int(hist.sum())
    if n == 0:
        return float("nan")
    k = int(np.searchsorted(np.cumsum(hist), max(1, math.ceil(q * n))))
    return float(10.0 ** ((k + first_bin) / _BINS_PER_DECADE))


def _moving_quantile(hist: np.ndarray, q: float) -> tuple[float, int]:
    """The ``q`` quantile of a histogram of second differences (m, bin centre) with exact
    repeats (its first bin: 1 mm and less) left out, and how many it is over."""
    moving = hist.copy()
    moving[0] = 0
    return _log_quantile(moving, _J_MIN, q), int(moving.sum())


def _log_bins(values: np.ndarray, first_bin: int, last_bin: int) -> np.ndarray:
    """Counts per bin of the histograms above: bin ``k`` (from ``first_bin``) holds the
    values with ``round(_BINS_PER_DECADE * log10(value)) == k + first_bin``, values below
    ``1e-9`` taken as ``1e-9`` and bins beyond either end clipped to it."""
    with np.errstate(divide="ignore"):
        k = np.rint(_BINS_PER_DECADE * np.log10(np.maximum(values, 1e-9)))
    k = np.clip(k.astype(np.int64), first_bin, last_bin)
    return np.bincount(k - first_bin, minlength=last_bin - first_bin + 1)


def _second_differences(
    t: np.ndarray, lat: np.ndarray, lon: np.ndarray, lag: int
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Over each triple of fixes ``i``, ``i + lag``, ``i + 2 lag`` whose two steps are
    proper: the steps (s) and where the third fix lands beyond the first two's
    straight-line extrapolation over its step (m)."""
    if t.size < 2 * lag + 1:
        empty = np.empty(0)
        return empty, empty, empty
    dt = t[lag:] - t[:-lag]
    d1, d2 = dt[:-lag], dt[lag:]
    i = np.flatnonzero((d1 >= REPEAT_S) & (d2 >= REPEAT_S))
    d1, d2 = d1[i], d2[i]
    per_deg = math.radians(1.0) * EARTH_MEAN_RADIUS_M
    scale = np.cos(np.radians(lat[i + lag])) * per_deg
    east01 = ((lon[i + lag] - lon[i] + 540.0) % 360.0 - 180.0) * scale  # across +-180 too
    east12 = ((lon[i + 2 * lag] - lon[i + lag] + 540.0) % 360.0 - 180.0) * scale
    ratio = d2 / d1
    de = east12 - east01 * ratio
    dn = ((lat[i + 2 * lag] - lat[i + lag]) - (lat[i + lag] - lat[i]) * ratio) * per_deg
    return d1, d2, np.hypot(de, dn)


def _comparable(d1: np.ndarray, d2: np.ndarray) -> np.ndarray:
    """Triples whose longer step is at most :data:`INTERLEAVE_STEP_RATIO` times the shorter."""
    within: np.ndarray = np.maximum(d1, d2) <= INTERLEAVE_STEP_RATIO * np.minimum(d1, d2)
    return within


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
        # Of those, the ones whose position differs from the fix before (a distinct fix
        # in the same instant: the time column is coarser than the fixes come).
        self.moved_repeats = 0
        self.fast = 0
        self.fastest = 0.0
        self.second_diff_hist = np.zeros(_J_MAX - _J_MIN + 1, dtype=np.int64)
        # Second differences over consecutive fixes and over every other fix, for
        # ``interleaved sources``.
        self.consecutive_hist = np.zeros(_J_MAX - _J_MIN + 1, dtype=np.int64)
        self.alternate_hist = np.zeros(_J_MAX - _J_MIN + 1, dtype=np.int64)
        self.speed_ratio_hist = np.zeros(_R_MAX - _R_MIN + 1, dtype=np.int64)
        # Steps the positions drive at WITNESS_MIN_SPEED_MPS or more with a reported speed,
        # and of them those whose reported speed is below STILL_SPEED_MPS.
        self.speed_steps = 0
        self.still_speed_steps = 0
        # Time between position updates (fixes whose position differs from the one before),
        # binned as ``hist``; and proper steps that repeat the position before exactly.
        self.update_hist = np.zeros(_K_MAX - _K_MIN + 1, dtype=np.int64)
        self.position_repeats = 0
        # Valid fixes that come, in file order, before a fix above them in their track;
        # and each track's latest time so far (file order).
        self.backward = 0
        self._latest: dict[str, float] = {}
        # Valid fixes per track, and the name of the column the tracks come from.
        self.fixes_per_track: dict[str, int] = {}
        self.track_column: str | None = None
        # Fixes whose latitude and longitude both lie on each grid of COARSE_GRIDS_DEG.
        self.on_grid = np.zeros(len(COARSE_GRIDS_DEG), dtype=np.int64)
        # Per reading of HEADING_READINGS, |reported heading - chord bearing| in 1-degree bins.
        self.heading_diff_hist = np.zeros((len(HEADING_READINGS), 181), dtype=np.int64)
        #: How the speed column was read (``fixes.attrs``): its name and unit.
        self.speed_column: str | None = None
        self.speed_unit = "m/s"
        self.heading_column: str | None = None
        # The last four fixes of each track (t, lat, lon), oldest first.
        self._last: dict[str, list[tuple[float, float, float]]] = {}
        # Each track's last position update (its time).
        self._last_update: dict[str, float] = {}
        # Each track's last fix on the witness baseline (t, lat, lon, speed, heading).
        self._last_kept: dict[str, tuple[float, float, float, float, float]] = {}
        #: What the reader assumed about the columns (``fixes.attrs["notes"]``), once each.
        self.notes: list[str] = []

    def to_state(self) -> dict[str, Any]:
        """What the checks have gathered, as plain JSON values (histograms as their non-zero
        bins): a stream worker stores it with a vehicle's detector and goes on from it
        with :meth:`from_state`, on any worker, as if it had seen every fix itself."""

        def bins(hist: np.ndarray) -> list[list[int]]:
            flat = hist.reshape(-1)
            return [[int(i), int(flat[i])] for i in np.flatnonzero(flat)]

        return {
            "rates": [self.min_rate_hz, self.max_rate_hz],
            "hist": bins(self.hist),
            "repeats": self.repeats,
            "moved_repeats": self.moved_repeats,
            "fast": self.fast,
            "fastest": self.fastest,
            "second_diff_hist": bins(self.second_diff_hist),
            "consecutive_hist": bins(self.consecutive_hist),
            "alternate_hist": bins(self.alternate_hist),
            "speed_ratio_hist": bins(self.speed_ratio_hist),
            "heading_diff_hist": bins(self.heading_diff_hist),
            "update_hist": bins(self.update_hist),
            "position_repeats": self.position_repeats,
            "last_update": dict(self._last_update),
            "speed_steps": self.speed_steps,
            "still_speed_steps": self.still_speed_steps,
            "backward": self.backward,
            "latest": dict(self._latest),
            "fixes_per_track": dict(self.fixes_per_track),
            "track_column": self.track_column,
            "on_grid": [int(n) for n in self.on_grid],
            "speed_column": self.speed_column,
            "speed_unit": self.speed_unit,
            "heading_column": self.heading_column,
            "last": {k: [list(f) for f in v] for k, v in self._last.items()},
            "last_kept": {k: list(v) for k, v in self._last_kept.items()},
            "notes": list(self.notes),
        }

    @classmethod
    def from_state(cls, state: Mapping[str, Any]) -> InputChecks:
        """The checks :meth:`to_state` wrote. A state that is not one (a missing key, a bin
        out of range, a wrong type) raises ``ValueError``, ``KeyError`` or ``TypeError``."""
        low, high = (float(r) for r in state["rates"])
        checks = cls(low, high)

        def fill(hist: np.ndarray, given: Any) -> None:
            flat = hist.reshape(-1)
            for i, n in given:
                if not 0 <= int(i) < flat.size or int(n) < 0:
                    raise ValueError(f"histogram bin {i!r} of {n!r} is out of range")
                flat[int(i)] = int(n)

        fill(checks.hist, state["hist"])
        fill(checks.second_diff_hist, state["second_diff_hist"])
        fill(checks.speed_ratio_hist, state["speed_ratio_hist"])
        fill(checks.heading_diff_hist, state["heading_diff_hist"])
        # States written before the position-update check have none of its facts: it
        # starts afresh from them.
        fill(checks.update_hist, state.get("update_hist", ()))
        fill(checks.consecutive_hist, state.get("consecutive_hist", ()))
        fill(checks.alternate_hist, state.get("alternate_hist", ()))
        checks.position_repeats = int(state.get("position_repeats", 0))
        checks.speed_steps = int(state.get("speed_steps", 0))
        checks.still_speed_steps = int(state.get("still_speed_steps", 0))
        checks.backward = int(state.get("backward", 0))
        checks._latest = {str(k): float(v) for k, v in dict(state.get("latest", {})).items()}
        checks.fixes_per_track = {
            str(k): int(v) for k, v in dict(state.get("fixes_per_track", {})).items()
        }
        column = state.get("track_column")
        if column is not None and not isinstance(column, str):
            raise TypeError(f"track_column is not a string: {column!r}")
        checks.track_column = column
        on_grid = [int(n) for n in state.get("on_grid", [0] * len(COARSE_GRIDS_DEG))]
        if len(on_grid) != len(COARSE_GRIDS_DEG) or min(on_grid) < 0:
            raise ValueError(f"on_grid {on_grid!r} is not one count per grid")
        checks.on_grid[:] = on_grid
        checks._last_update = {
            str(k): float(v) for k, v in dict(state.get("last_update", {})).items()
        }
        checks.repeats = int(state["repeats"])
        checks.moved_repeats = int(state.get("moved_repeats", 0))
        checks.fast = int(state["fast"])
        checks.fastest = float(state["fastest"])
        for name in ("speed_column", "heading_column"):
            value = state[name]
            if value is not None and not isinstance(value, str):
                raise TypeError(f"{name} is not a string: {value!r}")
            setattr(checks, name, value)
        checks.speed_unit = str(state["speed_unit"])
        checks._last = {
            str(k): [(float(a), float(b), float(c)) for a, b, c in v]
            for k, v in state["last"].items()
        }
        checks._last_kept = {
            str(k): (float(a), float(b), float(c), float(d), float(e))
            for k, (a, b, c, d, e) in state["last_kept"].items()
        }
        checks.notes = [str(n) for n in state["notes"]]
        return checks

    def add(self, fixes: pd.DataFrame) -> InputChecks:
        """Take in canonical fixes (columns ``track``, ``t``, ``lat``, ``lon``); returns ``self``."""
        for note in fixes.attrs.get("notes", ()):
            if note not in self.notes:
                self.notes.append(note)
        columns = fixes.attrs.get("columns")
        if "speed" in fixes.columns and self.speed_column is None:
            self.speed_column = getattr(columns, "speed", None) or "speed"
            self.speed_unit = str(fixes.attrs.get("speed_unit", "m/s"))
        if "heading" in fixes.columns and self.heading_column is None:
            self.heading_column = getattr(columns, "heading", None) or "heading"
        track_column = getattr(columns, "track", None)
        if self.track_column is None and track_column:
            self.track_column = str(track_column)
        none = np.full(len(fixes), np.nan)
        values = [
            fixes[c].to_numpy(dtype=np.float64) if c in fixes else none
            for c in ("t", "lat", "lon", "speed", "heading")
        ]
        tracks = fixes["track"].astype(str).to_numpy(dtype=object)
        for name, rows in pd.Series(tracks).groupby(tracks, sort=False).indices.items():
            self.add_track(str(name), *(v[rows] for v in values))
        return self

    def add_track(
        self,
        track: str,
        t: np.ndarray,
        lat: np.ndarray,
        lon: np.ndarray,
        speed: np.ndarray,
        heading: np.ndarray,
    ) -> InputChecks:
        """:meth:`add` for one track's fixes given as arrays (speed in m/s, heading in
        degrees modulo 360, NaN: none), without a table: what a stream worker feeds a
        few fixes at a time, where building a table would cost a hundred times the
        detector. The same facts as :meth:`add` of the same fixes; returns ``self``."""
        t, lat, lon, speed, heading = (
            np.asarray(v, dtype=np.float64) for v in (t, lat, lon, speed, heading)
        )
        if self.speed_column is None and not np.isnan(speed).all():
            self.speed_column, self.speed_unit = "speed", "m/s"
        if self.heading_column is None and not np.isnan(heading).all():
            self.heading_column = "heading"
        with np.errstate(invalid="ignore"):
            valid = (
                np.isfinite(t)
                & np.isfinite(lat)
                & np.isfinite(lon)
                & (np.abs(lat) <= 90.0)
                & (np.abs(lon) <= 180.0)
            )
        in_file = t[valid]
        if in_file.size:
            before = self._latest.get(track, -math.inf)
            latest = np.maximum.accumulate(np.r_[before, in_file])
            self.backward += int((in_file < latest[:-1]).sum())
            self._latest[track] = float(latest[-1])
        order = np.flatnonzero(valid)[np.argsort(t[valid], kind="stable")]
        if order.size:
            self._add_track(track, t[order], lat[order], lon[order], speed[order], heading[order])
        return self

    def _add_track(
        self,
        track: str,
        tt: np.ndarray,
        la: np.ndarray,
        lo: np.ndarray,
        speed: np.ndarray,
        heading: np.ndarray,
    ) -> None:
        """One track's valid fixes, in time order, into the histograms."""
        part = (tt, la, lo, speed, heading)
        self._grids(la, lo)
        self.fixes_per_track[track] = self.fixes_per_track.get(track, 0) + int(tt.size)
        last = self._last.get(track, [])
        k = len(last)
        if last and tt[0] >= last[-1][0]:
            # The track goes on: its last fixes (in time order) lead this chunk's; the
            # steps and triples among them were counted with the chunks before.
            tt = np.r_[[f[0] for f in last], tt]
            la = np.r_[[f[1] for f in last], la]
            lo = np.r_[[f[2] for f in last], lo]
        else:
            k = 0
            self._last_update.pop(track, None)  # no step from the fixes before: start afresh
        one, two, four = (max(k - n, 0) for n in (1, 2, 4))
        self._updates(track, tt[one:], la[one:], lo[one:])
        self._steps(tt[one:], la[one:], lo[one:])
        self._second_differences(tt[two:], la[two:], lo[two:])
        self._alternate_second_differences(tt[four:], la[four:], lo[four:])
        self._last[track] = [
            (float(a), float(b), float(c))
            for a, b, c in zip(tt[-4:], la[-4:], lo[-4:], strict=True)
        ]
        self._witness(track, part)

    def _witness(self, track: str, part: tuple[np.ndarray, ...]) -> None:
        """Histograms of the reported speed over the chord's speed, and of how far the
        reported heading (each reading of :data:`HEADING_READINGS`) is from the chord's
        bearing, over the steps that say something about them.

        The steps join the first fix of each :data:`WITNESS_BASELINE_S` of the track's
        time (so a 10 Hz receiver's chords span a second, like a 1 Hz one's, and its
        centimetres of noise stay a small part of them) and are used within the
        ``WITNESS_*`` limits. A step's reported value is the mean of its two fixes' (the
        circular mean for a heading; the one fix's where the other has none): on an arc of
        constant speed and curvature that is the chord's own speed and bearing.
        """
        values = list(part)
        if np.isnan(values[3]).all() and np.isnan(values[4]).all():
            return
        slot = np.floor(values[0] / WITNESS_BASELINE_S)
        first = np.r_[True, slot[1:] != slot[:-1]]
        kept = [v[first] for v in values]
        last = self._last_kept.get(track)
        if last is not None and kept[0][0] >= last[0]:
            # The track goes on from its last kept fix, unless this chunk opens in its slot.
            if np.floor(kept[0][0] / WITNESS_BASELINE_S) == np.floor(last[0] / WITNESS_BASELINE_S):
                kept = [v[1:] for v in kept]
            kept = [np.r_[x, v] for x, v in zip(last, kept, strict=True)]
        if kept[0].size:
            self._last_kept[track] = tuple(float(v[-1]) for v in kept)  # type: ignore[assignment]
        t, lat, lon, speed, heading = kept
        if t.size < 2:
            return
        dt = np.diff(t)
        chord = haversine_m(lat[:-1], lon[:-1], lat[1:], lon[1:])
        with np.errstate(divide="ignore", invalid="ignore"):
            v = chord / dt
            use = (
                (dt >= REPEAT_S)
                & (dt <= WITNESS_MAX_STEP_S)
                & (chord >= WITNESS_MIN_CHORD_M)
                & (v >= WITNESS_MIN_SPEED_MPS)
                & (v <= MAX_SPEED_MPS)
            )
        if not use.any():
            return
        i = np.flatnonzero(use)
        reported = _mean_of_two(speed[i], speed[i + 1])
        # Moving by the reported speed too: a fault's chord is fast while the car may stand,
        # and a step the car drove slowly says little about the witness.
        with np.errstate(invalid="ignore"):
            slow = reported < WITNESS_MIN_SPEED_MPS  # False where nan
            self.speed_steps += int(np.isfinite(reported).sum())
            self.still_speed_steps += int((reported < STILL_SPEED_MPS).sum())
        moving = np.isfinite(reported) & ~slow
        if moving.any():
            ratio = reported[moving] / v[i][moving]
            self.speed_ratio_hist += _log_bins(ratio, _R_MIN, _R_MAX)
        if np.isnan(heading).all():
            return
        i, reported = i[~slow], reported[~slow]
        # The chord's bearing, degrees clockwise from north (local flat approximation: a
        # chord is at most MAX_SPEED_MPS * WITNESS_MAX_STEP_S = 500 m long).
        north = (lat[i + 1] - lat[i]) * math.radians(1.0) * EARTH_MEAN_RADIUS_M
        east = (
            ((lon[i + 1] - lon[i] + 540.0) % 360.0 - 180.0)
            * math.radians(1.0)
            * EARTH_MEAN_RADIUS_M
            * np.cos(np.radians(0.5 * (lat[i] + lat[i + 1])))
        )
        bearing = np.degrees(np.arctan2(east, north))
        for k, ends in enumerate(_heading_readings(heading[i], heading[i + 1])):
            h = _circular_mean_deg(*ends)
            seen = np.isfinite(h)
            if not seen.any():
                continue
            diff = np.abs((h[seen] - bearing[seen] + 540.0) % 360.0 - 180.0)
            bins = np.clip(np.rint(diff).astype(np.int64), 0, 180)
            self.heading_diff_hist[k] += np.bincount(bins, minlength=181)

    def speed_agreement(self) -> tuple[float, float, int]:
        """``(share, typical, steps)``: the share of steps whose reported speed agrees with
        the chord's (:data:`SPEED_AGREEMENT`), the typical ratio of reported to chord speed
        (the median of the ratios within 10 % of the densest 5 % of them: where a wrong
        unit puts the clean steps, whatever the faults' steps do), and the steps; nan
        without any."""
        hist = self.speed_ratio_hist
        n = int(hist.sum())
        if n == 0:
            return float("nan"), float("nan"), 0
        r = np.arange(_R_MIN, _R_MAX + 1)
        within = np.abs(r) <= _BINS_PER_DECADE * math.log10(SPEED_AGREEMENT)
        # The densest 5 % of ratios, then the median of those within 10 % of its centre.
        half = max(1, round(_BINS_PER_DECADE * math.log10(1.05) / 2))
        dense = np.convolve(hist, np.ones(2 * half + 1, dtype=np.int64), mode="same")
        centre = int(np.argmax(dense))
        reach = round(_BINS_PER_DECADE * math.log10(1.1))
        lo = max(0, centre - reach)
        typical = _log_quantile(hist[lo : centre + reach + 1], _R_MIN + lo, 0.5)
        return float(hist[within].sum() / n), typical, n

    def heading_agreement(self, reading: int = 0) -> tuple[float, int]:
        """``(share, steps)``: the share of steps whose reported heading, read as
        :data:`HEADING_READINGS` ``[reading]`` (0: as the model reads it), is within
        :data:`HEADING_AGREEMENT_DEG` of the chord's bearing; nan without any."""
        hist = self.heading_diff_hist[reading]
        n = int(hist.sum())
        if n == 0:
            return float("nan"), 0
        return float(hist[: int(HEADING_AGREEMENT_DEG) + 1].sum() / n), n

    def _witness_warnings(self) -> list[tuple[str, str]]:
        """A reported speed or heading that contradicts the positions: the model would read
        the contradiction as faults on clean fixes (a speed in km/h read as m/s flagged a
        third of a clean Nevada drive's fixes)."""
        out: list[tuple[str, str]] = []
        share, ratio, n = self.speed_agreement()
        still = self.still_speed_steps
        if self.speed_steps >= MIN_WITNESS_STEPS and still >= 0.5 * self.speed_steps:
            text = (
                f"reported speed (column {self.speed_column!r}) is under {STILL_SPEED_MPS:g} "
                f"m/s on {still:,} of {self.speed_steps:,} steps the positions drive at "
                f"{WITNESS_MIN_SPEED_MPS:g} m/s or more ({100.0 * still / self.speed_steps:.0f} "
                "%): a placeholder (zeros), not a measurement? Leave it out with --speed-col "
                "''; a speed that contradicts the positions can make the model flag clean fixes"
            )
            out.append(("reported speed", text))
        elif n >= MIN_WITNESS_STEPS and share < MIN_AGREEMENT:
            written = _speed_written_in(ratio, self.speed_unit)
            if written is not None:
                fix = (
                    f"the values look like {written}: pass --speed-unit {written} "
                    f"(Python: speed_unit={written!r})"
                )
            else:
                fix = (
                    "check the column and its unit (--speed-unit m/s, km/h, mph or knots), "
                    "or leave it out with --speed-col ''"
                )
            text = (
                f"reported speed (column {self.speed_column!r}, read in {self.speed_unit}) "
                f"agrees with the speed between fixes on {100 * share:.0f} % of {n:,} moving "
                f"steps and is typically {ratio:.2f} times it: {fix}; a speed that contradicts "
                "the positions can make the model flag clean fixes"
            )
            out.append(("reported speed", text))
        share, n = self.heading_agreement()
        if n >= MIN_WITNESS_STEPS and share < MIN_AGREEMENT:
            best, name = max(
                (self.heading_agreement(k)[0], name)
                for k, name in enumerate(HEADING_READINGS)
                if k > 0
            )
            if best >= 1.0 - MIN_AGREEMENT:
                fix = (
                    f"read as {name} it agrees on {100 * best:.0f} %: convert it to degrees "
                    "clockwise from north"
                )
            else:
                fix = "check the column"
            text = (
                f"reported heading (column {self.heading_column!r}) agrees with the bearing "
                f"between fixes (within {HEADING_AGREEMENT_DEG:g} degrees) on "
                f"{100 * share:.0f} % of {n:,} moving steps; {fix}, or leave it out with "
                "--heading-col ''; a heading that contradicts the positions can make the model "
                "flag clean fixes"
            )
            out.append(("reported heading", text))
        return out

    def _second_differences(self, t: np.ndarray, lat: np.ndarray, lon: np.ndarray) -> None:
        """Histogram where each fix lands beyond the line its two predecessors draw (m), over
        triples whose two steps are proper and within 10 % of each other; and, over steps
        within :data:`INTERLEAVE_STEP_RATIO` of each other, the same for ``interleaved
        sources``."""
        d1, d2, size = _second_differences(t, lat, lon, 1)
        with np.errstate(invalid="ignore"):
            even = np.abs(d2 - d1) <= _TRIPLE_TOLERANCE * d1
        self.second_diff_hist += _log_bins(size[even], _J_MIN, _J_MAX)
        self.consecutive_hist += _log_bins(size[_comparable(d1, d2)], _J_MIN, _J_MAX)

    def _alternate_second_differences(
        self, t: np.ndarray, lat: np.ndarray, lon: np.ndarray
    ) -> None:
        """Histogram of the second differences over every other fix (``i``, ``i + 2``,
        ``i + 4``), for ``interleaved sources``."""
        d1, d2, size = _second_differences(t, lat, lon, 2)
        self.alternate_hist += _log_bins(size[_comparable(d1, d2)], _J_MIN, _J_MAX)

    def interleaved(self) -> tuple[float, float, int]:
        """Medians of the second differences over consecutive fixes and over every other
        fix (m, exact repeats left out; nan where none), and the fewer of their counts."""
        zigzag, n_zigzag = _moving_quantile(self.consecutive_hist, 0.5)
        smooth, n_smooth = _moving_quantile(self.alternate_hist, 0.5)
        return zigzag, smooth, min(n_zigzag, n_smooth)

    def second_difference_median(self) -> float:
        """Median second difference of the positions in metres (bin centre); nan if none."""
        return _log_quantile(self.second_diff_hist, _J_MIN, 0.5)

    def second_difference_quartile(self) -> tuple[float, int]:
        """Lower quartile of the second differences in metres (bin centre), exact repeats
        (1 mm and less) left out, and how many it is over; ``(nan, 0)`` if none."""
        return _moving_quantile(self.second_diff_hist, 0.25)

    def _updates(self, track: str, t: np.ndarray, lat: np.ndarray, lon: np.ndarray) -> None:
        """Times between the track's position updates into ``update_hist``: ``t[0]`` is the
        track's first fix or its last one already seen (the position before this chunk)."""
        dt = np.diff(t)
        proper = dt >= REPEAT_S
        changed = (lat[1:] != lat[:-1]) | (lon[1:] != lon[:-1])
        self.position_repeats += int((proper & ~changed).sum())
        self.moved_repeats += int((~proper & changed).sum())
        times = t[1:][proper & changed]
        last = self._last_update.get(track)
        if last is None:  # the track's first fix is its first update
            last = float(t[0])
        times = np.r_[last, times]
        gaps = np.diff(times)
        gaps = gaps[gaps >= REPEAT_S]
        self.update_hist += _log_bins(gaps, _K_MIN, _K_MAX)
        self._last_update[track] = float(times[-1])

    def _grids(self, lat: np.ndarray, lon: np.ndarray) -> None:
        """Count the fixes whose latitude and longitude both lie on each coarse grid."""
        for i, (cell, _) in enumerate(COARSE_GRIDS_DEG):
            on = np.ones(lat.size, dtype=bool)
            for x in (lat, lon):
                q = x / cell
                on &= np.abs(q - np.rint(q)) <= _GRID_TOLERANCE
            self.on_grid[i] += int(on.sum())

    @property
    def fixes_seen(self) -> int:
        """Valid fixes taken in, all tracks."""
        return sum(self.fixes_per_track.values())

    def coarse_grid(self) -> tuple[float, str] | None:
        """The coarsest grid (degrees, name) that holds :data:`COARSE_SHARE` of the fixes,
        over at least :data:`MIN_TRIPLES` of them; None if none does."""
        if self.fixes_seen < MIN_TRIPLES:
            return None
        for (cell, name), n in zip(COARSE_GRIDS_DEG, self.on_grid, strict=True):
            if n >= COARSE_SHARE * self.fixes_seen:
                return cell, name
        return None

    def update_quantile(self, q: float) -> float:
        """The ``q`` quantile of the times between position updates in seconds (histogram
        bin centre); nan if none."""
        return _log_quantile(self.update_hist, _K_MIN, q)

    def padded(self) -> tuple[float, int]:
        """Lower quartile of the times between position updates over the steps' upper
        quartile (nan where either is unknown) and how many updates it is over: see
        ``repeated fixes``."""
        updates = int(self.update_hist.sum())
        step = self.step_quantile(0.75)
        if updates == 0 or not math.isfinite(step):
            return float("nan"), updates
        return self.update_quantile(0.25) / step, updates

    def _steps(self, t: np.ndarray, lat: np.ndarray, lon: np.ndarray) -> None:
        dt = np.diff(t)
        if dt.size == 0:
            return
        proper = dt >= REPEAT_S
        self.repeats += int((~proper).sum())
        d = dt[proper]
        self.hist += _log_bins(d, _K_MIN, _K_MAX)
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
        return [text for _, text in self.findings()]

    def findings(self) -> list[tuple[str, str]]:
        """``(kind, sentence)`` per way the input is outside what the model was validated
        on: the sentences of :meth:`warnings`, each with its kind (``"slow rate"``,
        ``"reported speed"``...; a reader's note is its own kind), so that a stream can
        say each kind once, as the evidence for it comes in."""
        out: list[tuple[str, str]] = [(note, note) for note in self.notes]
        if self.backward >= MIN_TRIPLES and self.backward >= 0.25 * self.fixes_seen:
            text = (
                f"time runs backwards: {self.backward:,} of {self.fixes_seen:,} fixes "
                f"({100.0 * self.backward / self.fixes_seen:.0f} %) come before a fix above "
                "them in their track; each track is read in row order, so these are flagged "
                "invalid (invalid_reason). If the file is sorted newest first, or not by time, "
                "sort its rows by time"
            )
            out.append(("time runs backwards", text))
        lone = sum(1 for n in self.fixes_per_track.values() if n == 1)
        if self.fixes_seen >= MIN_TRIPLES and lone >= 0.5 * self.fixes_seen:
            column = f" (column {self.track_column!r})" if self.track_column else ""
            named = repr(self.track_column) if self.track_column else "the track column"
            text = (
                f"one-fix tracks: {lone:,} of {self.fixes_seen:,} fixes are alone in their "
                f"track{column}; the detector judges a fix against the fixes before it in its "
                f"track, so it flags none of them. If {named} numbers the rows or points rather "
                "than the vehicles or trips, name the track column with --track-col "
                "(--track-col '' reads the file as one track)"
            )
            out.append(("one-fix tracks", text))
        if self.steps == 0:
            return out
        median = self.step_quantile(0.5)
        slowest = 1.0 / self.min_rate_hz
        fastest = 1.0 / self.max_rate_hz
        if math.isfinite(median) and median > slowest * (1.0 + RATE_TOLERANCE):
            text = (
                f"median time step {median:.2g} s ({1.0 / median:.2g} Hz) is slower than the "
                f"slowest rate the model was validated on ({self.min_rate_hz:g} Hz, one fix every "
                f"{slowest:g} s): expect more false alarms and missed faults"
            )
            out.append(("slow rate", text))
        if math.isfinite(median) and median < fastest / (1.0 + RATE_TOLERANCE):
            text = (
                f"median time step {median:.2g} s ({1.0 / median:.2g} Hz) is faster than the "
                f"fastest rate the model was validated on ({self.max_rate_hz:g} Hz): results "
                "there are not measured"
            )
            out.append(("fast rate", text))
        if self.repeats > MAX_REPEAT_SHARE * self.steps or self.moved_repeats > 0:
            moved = ""
            if self.moved_repeats:
                moved = (
                    f", {self.moved_repeats:,} of them at a new position: the time column is "
                    "coarser than the fixes come (whole seconds from a receiver a little faster "
                    "than its nominal rate, or a logger's own clock); the step after each spans "
                    "two fixes in one time step, so the fix after it begins a new segment "
                    "(nothing is predicted across it)"
                )
            text = (
                f"repeated timestamps: {self.repeats:,} of {self.steps:,} time steps "
                f"({100.0 * self.repeats / self.steps:.1f} %) repeat the previous fix's timestamp "
                f"(within 1 ms){moved}. Each such fix is flagged invalid in every mode "
                "(invalid_reason 'time not after the previous fix'); write the times with "
                "sub-second resolution, or the receiver's own fix times"
            )
            out.append(("repeated timestamps", text))
        proper = int(self.hist.sum())
        if self.fast > MAX_FAST_STEPS and self.fast > MAX_FAST_SHARE * proper:
            text = (
                f"{self.fast:,} of {proper:,} time steps ({100.0 * self.fast / proper:.0f} %) "
                f"imply speeds above {MAX_SPEED_MPS:g} m/s (fastest {self.fastest:,.0f} m/s): "
                "check the time unit and the latitude/longitude columns, and whether the file "
                "holds several vehicles without a track column (--track-col); so many are "
                "not glitches of a car's receiver"
            )
            out.append(("implausible speeds", text))
        coarse = self.coarse_grid()
        if coarse is not None:
            cell, name = coarse
            half_m = 0.5 * cell * math.radians(1.0) * EARTH_MEAN_RADIUS_M
            text = (
                f"coarse coordinates: the latitudes and longitudes are rounded to {name} "
                f"({cell:.2g} degrees), which moves each fix by up to {half_m:.2g} m "
                "north-south; the model was trained on fixes to a metre or better and reads "
                "the rounding as noise or faults: expect false alarms; export the positions "
                "with more decimals (6 decimals of a degree are 0.1 m)"
            )
            out.append(("coarse coordinates", text))
        ratio, updates = self.padded()
        padded = coarse is None and updates >= MIN_UPDATES and ratio >= PADDED_RATIO
        if padded:
            update_s = self.update_quantile(0.5)
            text = (
                f"repeated fixes: the positions change every {update_s:.2g} s (median) while "
                f"fixes come every {median:.2g} s, and {self.position_repeats:,} of "
                f"{proper:,} time steps ({100.0 * self.position_repeats / max(proper, 1):.0f} %) "
                "repeat the position before exactly: a receiver's fixes re-sampled onto a "
                "faster clock. The model reads every row as a new fix, so each update looks "
                "like a jump after a standstill: expect false alarms; keep only the rows where "
                f"the position changes (one fix every {update_s:.2g} s) and detect on those"
            )
            out.append(("repeated fixes", text))
        zigzag, smooth, pairs = self.interleaved()
        interleaved = (
            coarse is None
            and not padded
            and pairs >= MIN_TRIPLES
            and zigzag >= INTERLEAVED_MIN_M
            and zigzag >= INTERLEAVED_RATIO * smooth
        )
        if interleaved:
            column = f" (column {self.track_column!r})" if self.track_column else ""
            text = (
                f"interleaved sources: consecutive fixes zig-zag {zigzag:.2g} m off the line "
                f"their two predecessors draw (median) while every other fix keeps to a "
                f"smooth path ({smooth:.2g} m): two receivers or vehicles in one track"
                f"{column}, their fixes alternating. The model reads the zig-zag as faults: "
                "expect false alarms; give each source its own track with --track-col (a "
                "column naming the receiver, device or vehicle)"
            )
            out.append(("interleaved sources", text))
        noise, triples = self.second_difference_quartile()
        if (
            coarse is None
            and not padded
            and not interleaved
            and triples >= MIN_TRIPLES
            and noise > NOISY_QUARTILE_M
        ):
            text = (
                f"noisy fixes: three in four fixes land more than {noise:.2g} m off the line "
                "their two predecessors draw (at most 1.3 m on every real drive the model "
                "was trained and validated on): a noisier receiver than the model has been "
                "measured on; expect false alarms on its ordinary noise"
            )
            out.append(("noisy fixes", text))
        out.extend(self._witness_warnings())
        q1, q3 = self.step_quantile(0.25), self.step_quantile(0.75)
        if not interleaved and math.isfinite(median) and q3 - q1 > IRREGULAR_IQR_RATIO * median:
            text = (
                f"irregular sampling: time steps between {q1:.2g} s and {q3:.2g} s (quartiles) "
                f"around a median of {median:.2g} s; the model was validated on evenly "
                "sampled drives (a file that merges receivers or vehicles without a track "
                "column looks so: name theirs with --track-col)"
            )
            out.append(("irregular sampling", text))
        return out


def _heading_readings(a: np.ndarray, b: np.ndarray) -> list[tuple[np.ndarray, np.ndarray]]:
    """Both ends' headings (canonical: the column's values modulo 360) as each reading of
    :data:`HEADING_READINGS` takes them, in degrees clockwise from north."""

    def radians(h: np.ndarray) -> np.ndarray:
        # Radians in [-pi, pi) came out of the modulo as 356.9-360: back to negative first.
        return np.degrees(np.where(h > 180.0, h - 360.0, h)) % 360.0

    return [(a, b), (radians(a), radians(b)), ((90.0 - a) % 360.0, (90.0 - b) % 360.0)]


def _mean_of_two(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """The mean of each pair of finite values (the one finite value where the other is
    not; nan where neither is), without ``np.nanmean``'s warning on all-nan pairs."""
    fa, fb = np.isfinite(a), np.isfinite(b)
    a0, b0 = np.where(fa, a, 0.0), np.where(fb, b, 0.0)
    out: np.ndarray = np.where(fa & fb, 0.5 * (a0 + b0), np.where(fa, a0, np.where(fb, b0, np.nan)))
    return out


def _circular_mean_deg(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """The mean direction of two headings in degrees (one where the other is nan)."""
    ra, rb = np.radians(a), np.radians(b)
    with np.errstate(invalid="ignore"):
        s = np.nansum(np.c_[np.sin(ra), np.sin(rb)], axis=1)
        c = np.nansum(np.c_[np.cos(ra), np.cos(rb)], axis=1)
    out: np.ndarray = np.degrees(np.arctan2(s, c))
    out[np.isnan(a) & np.isnan(b)] = np.nan
    return out


def _speed_written_in(ratio: float, read: str) -> str | None:
    """The unit whose values, read in unit ``read``, give this ratio of reported to true
    speed, or None."""
    for written, f_written in SPEED_UNITS.items():
        if written != read and abs(math.log(ratio * f_written / SPEED_UNITS[read])) <= math.log1p(
            SPEED_UNIT_TOLERANCE
        ):
            return written
    return None


def input_warnings(
    fixes: pd.DataFrame,
    *,
    min_rate_hz: float = VALIDATED_DEFAULT["min_rate_hz"],
    max_rate_hz: float = VALIDATED_DEFAULT["max_rate_hz"],
) -> list[str]:
    """The warnings of :class:`InputChecks` for one canonical fixes frame."""
    return InputChecks(min_rate_hz, max_rate_hz).add(fixes).warnings()

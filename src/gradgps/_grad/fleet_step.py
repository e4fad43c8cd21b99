"""``gradgps.FleetDetector``: many vehicles' streams, one compiled call per batch of fixes.

A :class:`~gradgps._grad.detector.Detector` per vehicle costs a Python call
per fix (several microseconds of dispatch around a step of about 1.5 µs).
:class:`FleetDetector` keeps every vehicle's state in contiguous arrays (the
segment parameters ``P`` one row per vehicle, the GRU hidden states one row
per vehicle, the pipeline states ``S`` end to end in one buffer, and the
counters, last times and frame origins as columns) and scores a whole batch
of fixes of any mix of vehicles with :meth:`FleetDetector.update_many`.

The rule is the Detector's, fix by fix, bit for bit (tested against
:class:`ReferenceFleet`, one Detector per vehicle, on random interleavings):

* the *common case*, a valid fix of a vehicle whose segment's period is
  final (more than ``PERIOD_STEPS`` fixes in) that continues that segment
  (no gap over ``max_gap_s``, within :data:`FRAME_RADIUS_M` of the segment's
  first fix), and every invalid fix, are handled by one numba loop over the
  batch (:func:`_fleet_kernel`): the same :func:`grad_step` and the same
  validity rule as the Detector;
* the *rare cases* (a vehicle's first fix, a new segment, the warm-up while
  the period is provisional, with its rebuilds and replays) stop that
  vehicle in the loop; its remaining fixes go through
  :meth:`FleetDetector._update_one`, the Detector's ``update`` written on the
  arrays, until the vehicle's period is final again, and then back through
  the loop. Other vehicles are not held up: each vehicle's fixes are
  processed in its own order, and vehicles do not share state.

States move between the two classes: :meth:`FleetDetector.get_state` of a
vehicle is exactly :meth:`Detector.get_state` of a Detector that saw the same
fixes, and either's state can be restored into the other.
"""

from __future__ import annotations

import math
import os
from collections.abc import Hashable, Iterable, Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numba
import numpy as np
import pandas as pd
from numpy.typing import NDArray

from .._result import (
    STEP_TOLERANCE_S,
    PointResult,
    as_number,
    encode_floats,
    fix_quality_code,
    fix_reason,
    result_frame,
)
from .._tracks.geo import LocalFrame, far_apart_scalar
from .defaults import FRAME_RADIUS_M, MIN_STEP_S
from .detector import _STATE_FORMAT, Detector, _time_number
from .pipeline import (
    N_POINT_OUT,
    O_ALERT,
    O_BIAS,
    O_FLAG,
    O_LAT,
    O_LON,
    O_SCORE,
    O_TIME,
    PERIOD_STEPS,
    grad_step,
    new_state,
    new_work,
    warmup_periods,
)
from .time_classifier import TIME_TYPES

__all__ = ["FleetDetector", "FleetResult", "ReferenceFleet"]

FloatArray = NDArray[np.float64]

#: The invalid-fix reasons by the code :func:`_reason_code` gives, each written by
#: :func:`gradgps._result.fix_reason` itself (so the two can never word one differently).
REASONS: tuple[str, ...] = (
    "",
    fix_reason(math.nan, 1.0, 1.0),
    fix_reason(0.0, 1.0, 1.0, fix_quality=0),
    fix_reason(0.0, 1.0, 1.0, satellites=0),
    fix_reason(0.0, math.nan, 1.0),
    fix_reason(0.0, 91.0, 1.0),
    fix_reason(0.0, 1.0, math.nan),
    fix_reason(0.0, 1.0, 181.0),
    fix_reason(0.0, 0.0, 0.0),
    fix_reason(1.0, 1.0, 1.0, 1.0, MIN_STEP_S),
    fix_reason(1.0 + MIN_STEP_S / 2, 1.0, 1.0, 1.0, MIN_STEP_S),
)
_CODES = {text: k for k, text in enumerate(REASONS)}
_SHORTEST_STEP = MIN_STEP_S - STEP_TOLERANCE_S
# Kernel rounds per batch before the rest of it goes through the per-fix path (a vehicle
# that starts a new segment every few fixes would otherwise cost a round per segment).
_MAX_ROUNDS = 8


@numba.njit(cache=True)
def _reason_code(
    t: float, lat: float, lon: float, fresh: bool, last_t: float, receiver: int
) -> int:
    """:func:`gradgps._result.fix_reason` with ``min_step_s`` = MIN_STEP_S, as an index
    into :data:`REASONS` (``receiver``: 0, or 1 no fix, 2 no satellites)."""
    if not math.isfinite(t):
        return 1
    if receiver != 0:
        return 1 + receiver
    if not math.isfinite(lat):
        return 4
    if abs(lat) > 90.0:
        return 5
    if not math.isfinite(lon):
        return 6
    if abs(lon) > 180.0:
        return 7
    if lat == 0.0 and lon == 0.0:
        return 8
    if not fresh:
        if t <= last_t:
            return 9
        if t - last_t < _SHORTEST_STEP:
            return 10
    return 0


@numba.njit(cache=True)
def _fleet_kernel(
    Ps: FloatArray,
    Ss: FloatArray,
    s_off: NDArray[np.int64],
    s_len: NDArray[np.int64],
    Hs: Any,
    seg: NDArray[np.int64],
    last_t: FloatArray,
    lat0: FloatArray,
    lon0: FloatArray,
    gp: Any,
    work: Any,
    max_gap_s: float,
    slots: NDArray[np.int64],
    t: FloatArray,
    lat: FloatArray,
    lon: FloatArray,
    speed: FloatArray,
    heading: FloatArray,
    receiver: NDArray[np.int64],
    todo: NDArray[np.int64],
    out: FloatArray,
    code: NDArray[np.int64],
    deferred: NDArray[np.int64],
) -> int:
    """Fixes ``todo`` (batch positions, in order) of vehicles ``slots``: the common case and
    invalid fixes scored here, into ``out``/``code``; a vehicle's first rare fix and all its
    later ones are listed in ``deferred`` (returns how many)."""
    blocked = np.zeros(seg.size, np.bool_)
    n_def = 0
    for j in range(todo.size):
        i = todo[j]
        s = slots[i]
        if blocked[s]:
            deferred[n_def] = i
            n_def += 1
            continue
        fresh = seg[s] == 0
        c = _reason_code(t[i], lat[i], lon[i], fresh, last_t[s], receiver[i])
        if c != 0:
            code[i] = c
            continue
        dt = t[i] - last_t[s]
        if (
            seg[s] <= PERIOD_STEPS
            or dt > max_gap_s
            or far_apart_scalar(lat0[s], lon0[s], lat[i], lon[i], FRAME_RADIUS_M)
        ):
            blocked[s] = True
            deferred[n_def] = i
            n_def += 1
            continue
        a = s_off[s]
        grad_step(
            Ps[s],
            Ss[a : a + s_len[s]],
            Hs[s],
            gp,
            work,
            dt,
            lat[i],
            lon[i],
            speed[i],
            heading[i],
            out[i],
        )
        seg[s] += 1
        last_t[s] = t[i]
    return n_def


@dataclass(frozen=True)
class FleetResult:
    """Verdicts of :meth:`FleetDetector.update_many`, one entry per fix, in input order.

    The arrays hold what :class:`~gradgps._result.PointResult` holds per fix
    (``anomaly``, ``alert`` int8; ``score``, ``lat_clean``, ``lon_clean``
    float64; ``bias_type``, ``time_type``, ``invalid_reason`` str objects).
    """

    anomaly: NDArray[np.int8]
    score: FloatArray
    bias_type: NDArray[np.object_]
    time_type: NDArray[np.object_]
    lat_clean: FloatArray
    lon_clean: FloatArray
    alert: NDArray[np.int8]
    invalid_reason: NDArray[np.object_]

    def __len__(self) -> int:
        return int(self.score.size)

    def point(self, i: int) -> PointResult:
        """Fix ``i``'s verdict as the :class:`PointResult` a Detector returns."""
        return PointResult(
            anomaly=int(self.anomaly[i]),
            score=float(self.score[i]),
            bias_type=str(self.bias_type[i]),
            time_type=str(self.time_type[i]),
            lat_clean=float(self.lat_clean[i]),
            lon_clean=float(self.lon_clean[i]),
            alert=int(self.alert[i]),
            invalid_reason=str(self.invalid_reason[i]),
        )

    def to_frame(self, index: pd.Index | None = None) -> pd.DataFrame:
        """The verdicts as a DataFrame of the batch result columns (``anomaly`` ... ``invalid_reason``)."""
        return result_frame(
            pd.RangeIndex(len(self)) if index is None else index,
            self.invalid_reason,
            anomaly=self.anomaly,
            score=self.score,
            bias_type=self.bias_type,
            time_type=self.time_type,
            lat_clean=self.lat_clean,
            lon_clean=self.lon_clean,
            alert=self.alert,
        )


def _numbers(values: Any, n: int, convert: Any = as_number) -> FloatArray:
    """``values`` (one per fix) as float64, each read as ``convert`` reads one value."""
    if values is None:
        return np.full(n, np.nan)
    arr = np.asarray(values)
    if arr.shape != (n,):
        raise ValueError(f"expected {n} values, got an array of shape {arr.shape}")
    if arr.dtype.kind in "fiub":
        return arr.astype(np.float64)
    return np.array([convert(v) for v in arr.tolist()], np.float64)


def _times(values: Any, n: int) -> FloatArray:
    """Fix times as seconds, exactly as :meth:`Detector.update` reads each one."""
    arr = np.asarray(values)
    if arr.shape == (n,) and arr.dtype.kind == "M":
        ns = arr.astype("datetime64[ns]")
        out = ns.astype(np.int64).astype(np.float64) / 1e9
        out[np.isnat(ns)] = np.nan
        return out
    return _numbers(values, n, _time_number)


def _readings(values: Any, n: int) -> FloatArray:
    x = _numbers(values, n)
    return np.where(np.isfinite(x), x, np.nan)


def _receiver_codes(fix_quality: Any, satellites: Any, n: int) -> NDArray[np.int64]:
    """Per fix: 0, or 1 (receiver reports no fix), 2 (0 satellites), as
    :func:`gradgps._result.receiver_reason` decides."""
    codes = np.zeros(n, np.int64)
    if satellites is not None:
        codes[_numbers(satellites, n) == 0.0] = 2
    if fix_quality is not None:
        q = np.asarray(fix_quality, dtype=object)
        if q.shape != (n,):
            raise ValueError(f"expected {n} fix qualities, got shape {q.shape}")
        no_fix = np.array([fix_quality_code(v) == 0.0 for v in q.tolist()], bool)
        codes[no_fix] = 1
    return codes


def _encode(values: NDArray[Any]) -> list[float | str]:
    """:func:`gradgps._result.encode_floats` of an array, without the per-value Python loop."""
    out: list[float | str] = values.tolist()
    bad = np.flatnonzero(~np.isfinite(values))
    for k in bad.tolist():
        x = out[k]
        assert isinstance(x, float)
        out[k] = "nan" if math.isnan(x) else "inf" if x > 0 else "-inf"
    return out


class FleetDetector:
    """GRAD for a fleet: every vehicle's streaming state in contiguous arrays, one compiled
    call per batch of fixes (see the module docstring).

    ``model``, ``threshold``: as for :class:`Detector`. Vehicles are any hashable ids
    (compared as Python objects: ``"7"`` and ``7`` are two vehicles); a vehicle is made
    on first sight and kept until :meth:`drop`.
    """

    def __init__(
        self,
        model: str | os.PathLike[str] | None = None,
        *,
        threshold: float | None = None,
        capacity: int = 64,
    ) -> None:
        self.model = model
        self.threshold = threshold
        self._template = Detector(model, threshold=threshold)
        m = self._template.model_
        self.model_ = m
        self._gp = m.gru_params
        self._max_gap = float(m.params.max_gap_s)
        self._h_len = int(m.dims[1] + m.dims[2])
        P0 = m.params.array(1.0, LocalFrame(0.0, 0.0), m.dims)
        self._n_p = int(P0.size)
        self._work = new_work(P0)
        self._bias_names = np.array([*m.bias_classes, "none"], dtype=object)
        self._time_names = np.array([*TIME_TYPES, "none"], dtype=object)
        self._reasons = np.array(REASONS, dtype=object)
        self._index: dict[Hashable, int] = {}
        self._names: list[Hashable | None] = []
        self._free: list[int] = []
        cap = max(int(capacity), 1)
        self._seg = np.zeros(cap, np.int64)
        self._last = np.full(cap, np.nan)
        self._lat0 = np.full(cap, np.nan)
        self._lon0 = np.full(cap, np.nan)
        self._period = np.ones(cap)
        self._P = np.zeros((cap, self._n_p))
        self._H = np.zeros((cap, self._h_len), np.float32)
        self._s_off = np.zeros(cap, np.int64)
        self._s_len = np.zeros(cap, np.int64)
        self._s_cap = np.zeros(cap, np.int64)
        self._S = np.zeros(cap * int(new_state(P0).size))
        self._s_used = 0
        # The segment's fixes while its period is provisional, per slot (see Detector).
        self._warm: list[list[tuple[float, float, float, float, float]]] = []

    # -- vehicles --------------------------------------------------------------

    def __len__(self) -> int:
        return len(self._index)

    def __contains__(self, vehicle: object) -> bool:
        return vehicle in self._index

    @property
    def vehicles(self) -> list[Hashable]:
        """The vehicles held, in order of first sight."""
        return list(self._index)

    def _grow(self, need: int) -> None:
        cap = self._seg.size
        if need <= cap:
            return
        new = max(need, 2 * cap)

        def grown(a: NDArray[Any], fill: float) -> NDArray[Any]:
            b = np.full((new, *a.shape[1:]), fill, a.dtype)
            b[:cap] = a
            return b

        self._seg = grown(self._seg, 0)
        self._last = grown(self._last, np.nan)
        self._lat0 = grown(self._lat0, np.nan)
        self._lon0 = grown(self._lon0, np.nan)
        self._period = grown(self._period, 1.0)
        self._P = grown(self._P, 0.0)
        self._H = grown(self._H, 0.0)
        self._s_off = grown(self._s_off, 0)
        self._s_len = grown(self._s_len, 0)
        self._s_cap = grown(self._s_cap, 0)

    def _slot(self, vehicle: Hashable) -> int:
        """The slot of ``vehicle``, made (fresh) on first sight."""
        s = self._index.get(vehicle)
        if s is not None:
            return s
        if self._free:
            s = self._free.pop()
            self._names[s] = vehicle
        else:
            s = len(self._names)
            self._grow(s + 1)
            self._names.append(vehicle)
            self._warm.append([])
        self._index[vehicle] = s
        self._clear(s)
        return s

    def _clear(self, s: int) -> None:
        self._seg[s] = 0
        self._last[s] = np.nan
        self._lat0[s] = self._lon0[s] = np.nan
        self._period[s] = 1.0
        self._s_len[s] = 0
        self._warm[s] = []

    def drop(self, vehicle: Hashable) -> None:
        """Forget ``vehicle`` (its next fix starts it afresh); nothing happens for an unknown one."""
        s = self._index.pop(vehicle, None)
        if s is not None:
            self._clear(s)
            self._names[s] = None
            self._free.append(s)

    def _slots(self, vehicle_ids: Iterable[Hashable]) -> NDArray[np.int64]:
        get = self._index.get
        ids = list(vehicle_ids)
        found = [get(v, -1) for v in ids]
        if -1 in found:
            found = [s if s >= 0 else self._slot(v) for v, s in zip(ids, found, strict=True)]
        return np.array(found, np.int64)

    # -- one vehicle's segment ---------------------------------------------------

    def _store_segment(self, s: int, P: FloatArray, S: FloatArray) -> None:
        """Make ``P``/``S`` slot ``s``'s segment (its S region reused when big enough)."""
        n = S.size
        if n > self._s_cap[s]:
            if self._s_used + n > self._S.size:
                self._compact(n)
            self._s_off[s] = self._s_used
            self._s_cap[s] = n
            self._s_used += n
        a = int(self._s_off[s])
        self._S[a : a + n] = S
        self._s_len[s] = n
        self._P[s] = P

    def _compact(self, extra: int) -> None:
        """Lay the live S regions end to end in a buffer with room for ``extra`` more."""
        free = set(self._free)
        live = [s for s in range(len(self._names)) if s not in free and self._s_cap[s] > 0]
        used = int(sum(int(self._s_cap[s]) for s in live))
        buf = np.zeros(max(2 * (used + extra), 1024))
        at = 0
        for s in live:
            a, n = int(self._s_off[s]), int(self._s_cap[s])
            buf[at : at + n] = self._S[a : a + n]
            self._s_off[s] = at
            at += n
        for s in free:
            self._s_cap[s] = 0
        self._S = buf
        self._s_used = at

    def _new_segment(self, s: int, period: float) -> None:
        m = self.model_
        self._period[s] = period
        P = m.params.array(period, LocalFrame(float(self._lat0[s]), float(self._lon0[s])), m.dims)
        self._store_segment(s, P, new_state(P))
        self._H[s] = 0.0

    def _step(
        self, s: int, dt: float, lat: float, lon: float, speed: float, heading: float, out: Any
    ) -> None:
        a = int(self._s_off[s])
        grad_step(
            self._P[s],
            self._S[a : a + int(self._s_len[s])],
            self._H[s],
            self._gp,
            self._work,
            dt,
            lat,
            lon,
            speed,
            heading,
            out,
        )

    def _update_one(
        self,
        s: int,
        t: float,
        lat: float,
        lon: float,
        speed: float,
        heading: float,
        fix_quality: Any,
        satellites: Any,
        out: FloatArray,
    ) -> str:
        """:meth:`Detector.update` on slot ``s``: writes the outputs into ``out``, returns
        the invalid reason (``""`` for a usable fix)."""
        seg = int(self._seg[s])
        last = None if seg == 0 else float(self._last[s])
        reason = fix_reason(
            t, lat, lon, last, MIN_STEP_S, fix_quality=fix_quality, satellites=satellites
        )
        if reason:
            return reason
        fix = (t, lat, lon, speed, heading)
        warm = self._warm[s]
        dt = 0.0 if last is None else t - last
        if (
            last is None
            or dt > self._max_gap
            or far_apart_scalar(self._lat0[s], self._lon0[s], lat, lon, FRAME_RADIUS_M)
        ):
            self._lat0[s], self._lon0[s] = lat, lon
            self._warm[s] = [fix]
            seg = 0
            self._new_segment(s, 1.0)
            self._step(s, 0.0, lat, lon, speed, heading, out)
        elif warm:
            warm.append(fix)
            period = warmup_periods([w[0] for w in warm])[-1]
            if period != self._period[s]:
                self._new_segment(s, period)
                for j, w in enumerate(warm):
                    self._step(s, w[0] - warm[j - 1][0] if j else 0.0, *w[1:], out)
            else:
                self._step(s, dt, lat, lon, speed, heading, out)
            if len(warm) > PERIOD_STEPS:
                self._warm[s] = []  # the period is final
        else:
            self._step(s, dt, lat, lon, speed, heading, out)
        self._seg[s] = seg + 1
        self._last[s] = t
        return ""

    # -- batches -------------------------------------------------------------------

    def update(
        self,
        vehicle: Hashable,
        t: Any,
        lat: float,
        lon: float,
        speed: float | None = None,
        heading: float | None = None,
        *,
        fix_quality: Any = None,
        satellites: Any = None,
    ) -> PointResult:
        """One fix of one vehicle, as :meth:`Detector.update` scores it."""
        return self.update_many(
            [vehicle],
            [t],
            [lat],
            [lon],
            None if speed is None else [speed],
            None if heading is None else [heading],
            fix_quality=None if fix_quality is None else [fix_quality],
            satellites=None if satellites is None else [satellites],
        ).point(0)

    def update_many(
        self,
        vehicle_ids: Sequence[Hashable] | NDArray[Any],
        t: Any,
        lat: Any,
        lon: Any,
        speed: Any = None,
        heading: Any = None,
        *,
        fix_quality: Any = None,
        satellites: Any = None,
    ) -> FleetResult:
        """Score a batch of fixes of any vehicles; fix ``i`` is ``vehicle_ids[i]``'s next fix.

        Each argument holds one value per fix (``speed``, ``heading``,
        ``fix_quality``, ``satellites`` may be ``None``: not reported), read as
        :meth:`Detector.update` reads one value: times are seconds or
        datetimes; a missing or non-numeric value is NaN. Each vehicle's
        fixes are taken in batch order, and its verdicts are those of one
        Detector that saw its fixes one by one, bit for bit. Never raises on
        bad values (they come back flagged with ``invalid_reason``).
        """
        slots = self._slots(vehicle_ids)
        n = slots.size
        t_f = _times(t, n)
        lat_f = _numbers(lat, n)
        lon_f = _numbers(lon, n)
        speed_f = _readings(speed, n)
        heading_f = _readings(heading, n)
        receiver = _receiver_codes(fix_quality, satellites, n)
        out = np.full((n, N_POINT_OUT), np.nan)
        code = np.zeros(n, np.int64)
        other: dict[int, str] = {}  # reasons not in REASONS (none today)
        todo = np.arange(n, dtype=np.int64)
        deferred = np.empty(n, np.int64)
        for round_ in range(_MAX_ROUNDS + 1):
            if round_ < _MAX_ROUNDS:
                n_def = _fleet_kernel(
                    self._P,
                    self._S,
                    self._s_off,
                    self._s_len,
                    self._H,
                    self._seg,
                    self._last,
                    self._lat0,
                    self._lon0,
                    self._gp,
                    self._work,
                    self._max_gap,
                    slots,
                    t_f,
                    lat_f,
                    lon_f,
                    speed_f,
                    heading_f,
                    receiver,
                    todo,
                    out,
                    code,
                    deferred,
                )
                rest = deferred[:n_def].tolist()
            else:
                rest = todo.tolist()  # the last round: all through the per-fix path
            if not rest:
                break
            back: list[int] = []
            final: set[int] = set()
            for i in rest:
                s = int(slots[i])
                if s in final:
                    back.append(i)  # its period is final again: back to the kernel
                    continue
                reason = self._update_one(
                    s,
                    float(t_f[i]),
                    float(lat_f[i]),
                    float(lon_f[i]),
                    float(speed_f[i]),
                    float(heading_f[i]),
                    None if fix_quality is None else fix_quality[i],
                    None if satellites is None else satellites[i],
                    out[i],
                )
                if reason:
                    k = _CODES.get(reason)
                    if k is None:
                        other[i] = reason
                    else:
                        code[i] = k
                if round_ < _MAX_ROUNDS and self._seg[s] > PERIOD_STEPS:
                    final.add(s)
            if not back:
                break
            todo = np.array(back, np.int64)
        return self._result(out, code, other)

    def _result(
        self, out: FloatArray, code: NDArray[np.int64], other: dict[int, str]
    ) -> FleetResult:
        invalid = code != 0
        if other:
            invalid[list(other)] = True
        reasons = self._reasons[code]
        for i, text in other.items():
            reasons[i] = text
        ok = ~invalid
        bias = np.full(code.size, len(self._bias_names) - 1, np.int64)
        bias[ok] = out[ok, O_BIAS].astype(np.int64)
        kind = np.full(code.size, len(self._time_names) - 1, np.int64)
        kind[ok] = out[ok, O_TIME].astype(np.int64)
        anomaly = np.ones(code.size, np.int8)
        anomaly[ok] = out[ok, O_FLAG].astype(np.int8)
        alert = np.zeros(code.size, np.int8)
        alert[ok] = out[ok, O_ALERT].astype(np.int8)
        return FleetResult(
            anomaly=anomaly,
            score=out[:, O_SCORE].copy(),
            bias_type=self._bias_names[bias],
            time_type=self._time_names[kind],
            lat_clean=out[:, O_LAT].copy(),
            lon_clean=out[:, O_LON].copy(),
            alert=alert,
            invalid_reason=reasons,
        )

    # -- states ----------------------------------------------------------------------

    def get_state(self, vehicle: Hashable) -> dict[str, Any]:
        """``vehicle``'s state, exactly as :meth:`Detector.get_state` of a Detector that saw its
        fixes (restore it in either class). A vehicle not held is a fresh detector."""
        det = self._template  # never fed: its state is a fresh detector's
        s = self._index.get(vehicle)
        if s is None:
            return det.get_state()
        seg = int(self._seg[s])
        state: dict[str, Any] = {
            "format": _STATE_FORMAT,
            "model_checksum": self.model_.checksum,
            "settings_checksum": det._settings,
            "threshold": self.model_.params.threshold,
            "frame": None,
            "last_t": None,
            "segment_count": seg,
            "period": float(self._period[s]),
            "warm": [encode_floats(w) for w in self._warm[s]],
            "S": None,
            "H": None,
        }
        if seg:
            a, n = int(self._s_off[s]), int(self._s_len[s])
            state["frame"] = [float(self._lat0[s]), float(self._lon0[s])]
            state["last_t"] = float(self._last[s])
            state["S"] = _encode(self._S[a : a + n])
            state["H"] = _encode(self._H[s])
        return state

    def set_state(self, vehicle: Hashable, state: Mapping[str, Any]) -> None:
        """Restore ``vehicle`` from a :meth:`get_state` (or :meth:`Detector.get_state`) state of
        the same model and settings. A state the Detector would refuse raises
        :class:`~gradgps.ConfigError` and leaves the vehicle as it was."""
        frame, last_t, seg, period, warm, P, S, H = self._template._checked_state(state)
        s = self._slot(vehicle)
        self._clear(s)
        if seg:
            self._lat0[s], self._lon0[s] = frame.lat0, frame.lon0
            self._last[s] = last_t
            self._seg[s] = seg
            self._period[s] = period
            self._warm[s] = [tuple(w) for w in warm]
            self._store_segment(s, P, S)
            self._H[s] = H


class ReferenceFleet:
    """The readable reference of :class:`FleetDetector`: one :class:`Detector` per vehicle,
    fed fix by fix. Same interface (``update_many``, ``get_state``, ``set_state``, ``drop``)
    and, by test, the same verdicts and states bit for bit; slower."""

    def __init__(
        self, model: str | os.PathLike[str] | None = None, *, threshold: float | None = None
    ) -> None:
        self.model = model
        self.threshold = threshold
        self.detectors: dict[Hashable, Detector] = {}

    def _detector(self, vehicle: Hashable) -> Detector:
        det = self.detectors.get(vehicle)
        if det is None:
            det = self.detectors[vehicle] = Detector(self.model, threshold=self.threshold)
        return det

    def update_many(
        self,
        vehicle_ids: Sequence[Hashable] | NDArray[Any],
        t: Any,
        lat: Any,
        lon: Any,
        speed: Any = None,
        heading: Any = None,
        *,
        fix_quality: Any = None,
        satellites: Any = None,
    ) -> FleetResult:
        def at(values: Any, i: int) -> Any:
            return None if values is None else values[i]

        results = [
            self._detector(v).update(
                t[i],
                lat[i],
                lon[i],
                at(speed, i),
                at(heading, i),
                fix_quality=at(fix_quality, i),
                satellites=at(satellites, i),
            )
            for i, v in enumerate(vehicle_ids)
        ]

        def column(name: str, dtype: Any) -> NDArray[Any]:
            return np.array([getattr(r, name) for r in results], dtype)

        return FleetResult(
            anomaly=column("anomaly", np.int8),
            score=column("score", np.float64),
            bias_type=column("bias_type", object),
            time_type=column("time_type", object),
            lat_clean=column("lat_clean", np.float64),
            lon_clean=column("lon_clean", np.float64),
            alert=column("alert", np.int8),
            invalid_reason=column("invalid_reason", object),
        )

    def get_state(self, vehicle: Hashable) -> dict[str, Any]:
        return self.detectors[vehicle].get_state()

    def set_state(self, vehicle: Hashable, state: Mapping[str, Any]) -> None:
        det = Detector(self.model, threshold=self.threshold).set_state(state)
        self.detectors[vehicle] = det

    def drop(self, vehicle: Hashable) -> None:
        self.detectors.pop(vehicle, None)

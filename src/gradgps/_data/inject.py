"""Seeded fault injection: the three benchmark protocols (see ``docs/protocols.md``).

The real drives carry no labels, so benchmarks corrupt them on purpose and
record exactly what was done. Three protocols:

``grad``
    Position faults after the paper's Table 1. Latitude and longitude are
    corrupted independently, in metres (north and east of the track's own
    tangent plane), by *transient*, *intermittent* and *permanent* episodes
    whose bias is *noise* or a *jump*. Rates are steered to their targets by
    a point budget (below), so a benchmark split gets the paper's mix, not
    just its expectation.
``gnss``
    ``grad`` plus the faults real receivers make, on both channels at once:
    a *freeze* (the last fix repeated while the vehicle moves), a *drift*
    (an offset growing at a few m/s: a spoofing take-over), *multipath*
    (correlated offsets of tens of metres) and an *outage* the receiver
    reports itself (fix quality 0, no satellites).
``sensor-grid``
    Faults in speed, longitudinal acceleration and yaw rate after van Wyk et
    al. (2020) / Javed et al. (2021): *instant*, *constant*, *bias* and
    *drift* faults, one table row (magnitude, duration) at a time: the rows
    of the paper's comparison table.

All take a table (any columns; track/time/lat/lon found as in
:func:`gradgps.to_fixes`), keep every input column, overwrite the corrupted
ones and append label columns. Same input and seed give the same bytes.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import pandas as pd

from .._exceptions import ConfigError, InputError
from .._result import invalid_reasons
from .._tracks.geo import LocalFrame
from .._tracks.track import ColumnMap, to_fixes, track_rows, units_per_degree

__all__ = [
    "BIAS_TYPES",
    "CONSTANT_MODES",
    "GNSS_RATES",
    "GNSS_TYPES",
    "GRAD_RATES",
    "GRAVITY",
    "SENSOR_CHANNELS",
    "SENSOR_GRID_ROWS",
    "SENSOR_TYPES",
    "TIME_TYPES",
    "SensorFaultRow",
    "gnss_rates",
    "grad_rates",
    "inject_freeze",
    "inject_gnss",
    "inject_grad",
    "inject_sensor_grid",
    "sensor_grid_rates",
    "sensor_grid_row",
    "with_accel_mps2",
    "with_fix_speed",
]

TIME_TYPES = ("transient", "intermittent", "permanent")
BIAS_TYPES = ("noise", "jump")
SENSOR_TYPES = ("instant", "constant", "bias", "drift")
SENSOR_CHANNELS = ("speed_mps", "accel_x_mps2", "gyro_z_dps")
GRAVITY = 9.80665

# ---------------------------------------------------------------- protocol grad

#: Target share of points per channel for each time type (paper Table 1, rounded).
GRAD_RATES = {"transient": 0.035, "intermittent": 0.033, "permanent": 0.033}
SEGMENT_POINTS = 400
MIN_GAP_POINTS = 10
TRANSIENT_POINTS = (1, 5)
INTERMITTENT_SPAN = (20, 60)
INTERMITTENT_BURSTS = (3, 6)
INTERMITTENT_BURST_POINTS = (1, 3)
INTERMITTENT_PAUSE = (3, 15)
PERMANENT_POINTS = (20, 100)
NOISE_PROBABILITY = 0.6
NOISE_M = (10.0, 50.0)
JUMP_M = (20.0, 200.0)

_TIME_RANK = {"none": 0, "transient": 1, "intermittent": 2, "permanent": 3}
_BIAS_RANK = {
    "none": 0,
    "noise": 1,
    "jump": 2,
    "freeze": 3,
    "drift": 4,
    "multipath": 5,
    "outage": 6,
}


@dataclass
class _Channel:
    """One channel of one track while episodes are being placed on it."""

    offset_m: np.ndarray
    time_type: np.ndarray
    bias_type: np.ndarray
    episode: np.ndarray

    @classmethod
    def empty(cls, n: int) -> _Channel:
        return cls(
            np.zeros(n),
            np.full(n, "none", dtype=object),
            np.full(n, "none", dtype=object),
            np.full(n, -1, dtype=np.int64),
        )

    def free_starts(self, lo: int, hi: int, span: int) -> np.ndarray:
        """Starts ``s`` in ``[lo, hi - span]`` whose ``[s, s+span)`` keeps the gap to every episode."""
        n = self.episode.size
        busy = np.r_[0, np.cumsum(self.episode >= 0)]
        starts = np.arange(lo, hi - span + 1)
        left = np.maximum(starts - MIN_GAP_POINTS, 0)
        right = np.minimum(starts + span + MIN_GAP_POINTS, n)
        free: np.ndarray = starts[busy[right] - busy[left] == 0]
        return free


def _intermittent_pattern(rng: np.random.Generator) -> np.ndarray:
    """Offsets (from the episode start) of the burst points of one intermittent episode.

    Bursts, burst lengths and pauses are drawn from their ranges; a draw whose
    span falls outside ``INTERMITTENT_SPAN`` is drawn again (about half are
    kept), so every bound in the protocol holds exactly.
    """
    while True:
        n_bursts = int(rng.integers(INTERMITTENT_BURSTS[0], INTERMITTENT_BURSTS[1] + 1))
        lengths = rng.integers(
            INTERMITTENT_BURST_POINTS[0], INTERMITTENT_BURST_POINTS[1] + 1, size=n_bursts
        )
        pauses = rng.integers(INTERMITTENT_PAUSE[0], INTERMITTENT_PAUSE[1] + 1, size=n_bursts - 1)
        starts = np.r_[0, np.cumsum(lengths[:-1] + pauses)]
        span = int(starts[-1] + lengths[-1])
        if INTERMITTENT_SPAN[0] <= span <= INTERMITTENT_SPAN[1]:
            points: np.ndarray = np.concatenate(
                [np.arange(s, s + k) for s, k in zip(starts, lengths, strict=True)]
            )
            return points


def _bias_offsets(rng: np.random.Generator, k: int, scale: float) -> tuple[str, np.ndarray]:
    """Bias type and the ``k`` offsets in metres of one episode."""
    if rng.random() < NOISE_PROBABILITY:
        sign = rng.choice(np.array([-1.0, 1.0]), size=k)
        return "noise", sign * rng.uniform(*NOISE_M, size=k) * scale
    sign1 = -1.0 if rng.random() < 0.5 else 1.0
    return "jump", np.full(k, sign1 * rng.uniform(*JUMP_M) * scale)


class _GradScheduler:
    """Places episodes on channels, steering each time type's share to its target.

    Each time type has a *budget* of anomalous points: every segment adds
    ``rate * segment length``; an episode drawn with ``k`` points is placed
    when the budget is at least ``k / 2`` (rounding, so the long-run share is
    unbiased) and then costs ``k``. An episode that does not fit keeps its
    budget for the next segment, and budgets carry from one track to the next
    (short drives cannot hold a permanent fault; the longer ones make up for
    it). The share over a data set is then within about half an episode of
    the target, where independent draws would miss it by several points of a
    percent on a few thousand fixes.
    """

    def __init__(self, rng: np.random.Generator, scale: float) -> None:
        self.rng = rng
        self.scale = scale
        self.budget = {"lat": dict.fromkeys(TIME_TYPES, 0.0), "lon": dict.fromkeys(TIME_TYPES, 0.0)}
        self.next_episode = 0

    def channel(self, name: str, n: int, base: _Channel | None = None) -> _Channel:
        """Episodes on one channel of ``n`` points; ``base``: a channel already holding
        episodes (protocol ``gnss``), which the new ones keep their gaps to."""
        ch = _Channel.empty(n) if base is None else base
        budget = self.budget[name]
        for lo in range(0, n, SEGMENT_POINTS):
            hi = min(lo + SEGMENT_POINTS, n)
            for kind in TIME_TYPES:
                budget[kind] += GRAD_RATES[kind] * (hi - lo)
            self._permanent(ch, budget, lo, hi)
            self._movable(ch, budget, lo, hi, "intermittent")
            self._movable(ch, budget, lo, hi, "transient")
        return ch

    def _permanent(self, ch: _Channel, budget: dict[str, float], lo: int, hi: int) -> None:
        if hi - lo < PERMANENT_POINTS[1]:
            return
        k = int(self.rng.integers(PERMANENT_POINTS[0], PERMANENT_POINTS[1] + 1))
        if budget["permanent"] >= k / 2 and ch.free_starts(hi - k, hi, k).size:
            self._place(ch, np.arange(hi - k, hi), "permanent")
            budget["permanent"] -= k

    def _movable(self, ch: _Channel, budget: dict[str, float], lo: int, hi: int, kind: str) -> None:
        while True:
            if kind == "intermittent":
                pattern = _intermittent_pattern(self.rng)
            else:
                pattern = np.arange(
                    int(self.rng.integers(TRANSIENT_POINTS[0], TRANSIENT_POINTS[1] + 1))
                )
            if budget[kind] < pattern.size / 2:
                return
            starts = ch.free_starts(lo, hi, int(pattern[-1]) + 1)
            if starts.size == 0:
                return
            start = int(starts[self.rng.integers(starts.size)])
            self._place(ch, start + pattern, kind)
            budget[kind] -= pattern.size

    def _place(self, ch: _Channel, points: np.ndarray, kind: str) -> None:
        bias, offsets = _bias_offsets(self.rng, points.size, self.scale)
        ch.offset_m[points] = offsets
        ch.time_type[points] = kind
        ch.bias_type[points] = bias
        ch.episode[points] = self.next_episode
        self.next_episode += 1


def _check_scale(scale: float) -> None:
    if not (np.isfinite(scale) and scale > 0):
        raise ConfigError(f"scale must be a positive finite number, got {scale}")


def _truth(
    table: pd.DataFrame, columns: ColumnMap | None
) -> tuple[pd.DataFrame, ColumnMap, np.ndarray, np.ndarray]:
    """The table's fixes, the column map that read them, and the true latitudes and
    longitudes every protocol corrupts copies of."""
    fixes = to_fixes(table, columns)
    cmap: ColumnMap = fixes.attrs["columns"]
    assert cmap.lat is not None
    assert cmap.lon is not None
    return (
        fixes,
        cmap,
        fixes["lat"].to_numpy(dtype=np.float64),
        fixes["lon"].to_numpy(dtype=np.float64),
    )


def _write_labels(result: pd.DataFrame, labels: dict[str, _Channel], use_lon: np.ndarray) -> None:
    """The per-point label columns every protocol writes: anomaly (either channel),
    per channel, and the point's bias and time type from its stronger channel."""
    la, lo = labels["lat"], labels["lon"]
    result["label_anomaly"] = ((la.episode >= 0) | (lo.episode >= 0)).astype(np.int8)
    result["label_lat"] = (la.episode >= 0).astype(np.int8)
    result["label_lon"] = (lo.episode >= 0).astype(np.int8)
    result["label_bias"] = np.where(use_lon, lo.bias_type, la.bias_type)
    result["label_time"] = np.where(use_lon, lo.time_type, la.time_type)
    for name, ch in labels.items():
        result[f"label_bias_{name}"] = ch.bias_type
        result[f"label_time_{name}"] = ch.time_type
        result[f"label_episode_{name}"] = ch.episode


def _write_channel(
    name: str,
    ch: _Channel,
    hit: np.ndarray,
    rows: np.ndarray,
    frame: LocalFrame,
    east: np.ndarray,
    north: np.ndarray,
    coords: dict[str, np.ndarray],
    out: _Channel,
) -> None:
    """Write one track's channel ``name`` (``"lat"``/``"lon"``): its offsets at ``hit``
    moved the true position (``east``, ``north`` in ``frame``) along that axis only and
    into ``coords[name]`` at those ``rows``; its labels into ``out`` at all ``rows``."""
    if name == "lat":
        coords[name][rows[hit]] = frame.to_geodetic(east[hit], north[hit] + ch.offset_m[hit])[0]
    else:
        coords[name][rows[hit]] = frame.to_geodetic(east[hit] + ch.offset_m[hit], north[hit])[1]
    out.offset_m[rows] = ch.offset_m
    out.time_type[rows] = ch.time_type
    out.bias_type[rows] = ch.bias_type
    out.episode[rows] = ch.episode


def inject_grad(
    table: pd.DataFrame, *, seed: int, scale: float = 1.0, columns: ColumnMap | None = None
) -> pd.DataFrame:
    """Corrupt positions with protocol ``grad``; return the table with labels appended.

    The latitude and longitude columns are overwritten where a channel is
    faulty (other values stay bit-identical); appended columns:
    ``label_anomaly``, ``label_lat``, ``label_lon`` (0/1), ``label_bias``,
    ``label_time`` (the point's combined labels, see below), the per-channel
    ``label_bias_lat/lon``, ``label_time_lat/lon``, ``label_episode_lat/lon``
    (episode id, -1 for none) and the truth ``lat_true``, ``lon_true``.

    Where both channels are faulty with different labels, the combined labels
    come from the episode with the longer-lived time type (permanent >
    intermittent > transient), then jump over noise, then latitude: the fault
    that decides what a recovery module can still do. Rows that are not usable
    fixes (time/lat/lon missing) are never corrupted.
    """
    _check_scale(scale)
    fixes, cmap, lat_true, lon_true = _truth(table, columns)
    n = len(fixes)
    lat = lat_true.copy()
    lon = lon_true.copy()
    labels = {name: _Channel.empty(n) for name in ("lat", "lon")}
    scheduler = _GradScheduler(np.random.default_rng(seed), scale)
    for rows in track_rows(fixes, invalid_reasons(fixes) == ""):
        frame = LocalFrame(float(lat_true[rows[0]]), float(lon_true[rows[0]]))
        east, north = frame.to_local(lat_true[rows], lon_true[rows])
        for name in ("lat", "lon"):
            ch = scheduler.channel(name, rows.size)
            coords = {"lat": lat, "lon": lon}
            _write_channel(
                name, ch, ch.episode >= 0, rows, frame, east, north, coords, labels[name]
            )

    la, lo = labels["lat"], labels["lon"]
    rank_lat = _rank(la.time_type, la.bias_type)
    rank_lon = _rank(lo.time_type, lo.bias_type)
    use_lon = rank_lon > rank_lat
    result = table.reset_index(drop=True).copy()
    # In the column's own unit (degrees, or degrees x 1e7 for a latitudeE7).
    result[cmap.lat] = lat * units_per_degree(cmap.lat)
    result[cmap.lon] = lon * units_per_degree(cmap.lon)
    _write_labels(result, labels, use_lon)
    result["lat_true"] = lat_true
    result["lon_true"] = lon_true
    return result


def _rank(time_type: np.ndarray, bias_type: np.ndarray) -> np.ndarray:
    t = np.array([_TIME_RANK[v] for v in time_type], dtype=np.int64)
    b = np.array([_BIAS_RANK[v] for v in bias_type], dtype=np.int64)
    return t * 10 + b


def grad_rates(labelled: pd.DataFrame) -> pd.DataFrame:
    """Achieved shares (percent of all rows) laid out like the paper's Table 1.

    Rows: the time types and ``total``; columns: ``lat``, ``lon`` (points
    faulty on that channel) and ``noise``, ``jump`` (faulty channel-points of
    that bias, both channels together, so noise + jump = lat + lon).
    """
    n = max(len(labelled), 1)
    table: dict[str, dict[str, float]] = {}
    for kind in (*TIME_TYPES, "total"):
        row: dict[str, float] = {}
        for ch in ("lat", "lon"):
            tt = labelled[f"label_time_{ch}"].to_numpy(dtype=object)
            row[ch] = 100.0 * float(np.sum(tt != "none" if kind == "total" else tt == kind)) / n
        for bias in BIAS_TYPES:
            count = 0
            for ch in ("lat", "lon"):
                tt = labelled[f"label_time_{ch}"].to_numpy(dtype=object)
                bt = labelled[f"label_bias_{ch}"].to_numpy(dtype=object)
                sel = (tt != "none") if kind == "total" else (tt == kind)
                count += int(np.sum(sel & (bt == bias)))
            row[bias] = 100.0 * count / n
        table[kind] = row
    return pd.DataFrame.from_dict(table, orient="index")


# ---------------------------------------------------------------- protocol gnss

#: The bias types protocol ``gnss`` adds to ``grad``'s noise and jump: faults real
#: receivers make. Each moves (or invalidates) both channels at once.
GNSS_TYPES = ("freeze", "drift", "multipath", "outage")
#: Target share of each track's usable fixes per added bias type (steered by a
#: point budget, as under ``grad``); ``grad``'s own time types keep their rates.
GNSS_RATES = {"freeze": 0.02, "drift": 0.05, "multipath": 0.02, "outage": 0.015}
#: Seconds a frozen fix repeats the last value (the hold's first to last held fix
#: lie within this span of the fix before it).
FREEZE_S = (3.0, 60.0)
#: m/s: a freeze starts only when the vehicle moves this fast over the step into
#: the hold (:data:`_FREEZE_ONSET_SPEED`), and moves at 2 m/s or more for at
#: least half of the held steps: a frozen fix of a stopped car is a true fix.
FREEZE_MOVING_MPS = 2.0
#: Seconds the offset of a drift grows, and the rate it grows at (m/s).
DRIFT_S = (20.0, 300.0)
DRIFT_RATE_MPS = (0.2, 3.0)
#: Probability that a drift holds its final offset to the end of the track (the
#: spoofer keeps the receiver) instead of snapping back to the truth.
DRIFT_HOLD_PROBABILITY = 0.5
#: Seconds a held drift keeps its final offset before the track ends.
DRIFT_HOLD_S = (10.0, 120.0)
#: Seconds a multipath burst lasts, the correlation time of its AR(1) offsets,
#: and the size of its offsets in metres.
MULTIPATH_S = (2.0, 20.0)
MULTIPATH_TAU_S = (2.0, 20.0)
MULTIPATH_M = (10.0, 80.0)
#: Radians the direction of a multipath offset wanders either side of its start.
MULTIPATH_TURN_RAD = np.pi / 4
#: Seconds an outage lasts; the probability that its positions are missing (NaN)
#: rather than frozen at the last fix; what the receiver reports meanwhile.
OUTAGE_S = (1.0, 30.0)
OUTAGE_MISSING_PROBABILITY = 0.5
OUTAGE_FIX_QUALITY = 0
OUTAGE_SATELLITES = 0
OUTAGE_HDOP = 99.99
#: Draws per bias type and track before the type gives up until the next track.
GNSS_TRIES = 60
#: The receiver-quality columns an outage writes when the input has none of its own.
QUALITY_COLUMNS = ("fix_quality", "satellites", "hdop")


@dataclass
class _GnssEpisode:
    """One placed episode of an added bias type, in positions of its track's rows."""

    kind: str
    start: int
    stop: int  # exclusive
    time_type: str
    east: np.ndarray  # written offsets (m) or, for freeze/outage, unused
    north: np.ndarray
    missing: bool = False


def _span(t: np.ndarray, start: int, seconds: float) -> int:
    """End (exclusive) of the fixes from ``start`` whose time is before ``t[start] + seconds``."""
    return int(np.searchsorted(t, t[start] + seconds, side="left"))


def _step_speeds(t: np.ndarray, east: np.ndarray, north: np.ndarray) -> np.ndarray:
    """Speed (m/s) over the step from each fix to the next; 0 after the last."""
    speed: np.ndarray = np.r_[
        np.hypot(np.diff(east), np.diff(north)) / np.maximum(np.diff(t), 1e-9), 0.0
    ]
    return speed


def _too_slow_to_freeze(step: np.ndarray, onset: int, steps: slice) -> bool:
    """Whether a frozen fix there would be a true fix, so no freeze is placed: the vehicle
    moves slower than :data:`_FREEZE_ONSET_SPEED` over step ``onset`` (into the hold), or at
    :data:`FREEZE_MOVING_MPS` or more over fewer than half of ``steps`` (the hold is a
    real stop)."""
    return bool(
        step[onset] < _FREEZE_ONSET_SPEED or (step[steps] >= FREEZE_MOVING_MPS).mean() < 0.5
    )


def _std_normal_cdf(x: np.ndarray) -> np.ndarray:
    """Φ, the standard normal distribution function, per element (in [0, 1])."""
    return np.array([0.5 * math.erfc(-v / math.sqrt(2.0)) for v in x.tolist()], dtype=np.float64)


class _GnssScheduler:
    """Places the added bias types on one track after another (budgets carry over)."""

    def __init__(self, rng: np.random.Generator, scale: float) -> None:
        self.rng = rng
        self.scale = scale
        self.budget = dict.fromkeys(GNSS_TYPES, 0.0)

    def track(self, t: np.ndarray, east: np.ndarray, north: np.ndarray) -> list[_GnssEpisode]:
        n = t.size
        busy = np.zeros(n, dtype=bool)
        step = _step_speeds(t, east, north)
        placed: list[_GnssEpisode] = []
        for kind in GNSS_TYPES:
            self.budget[kind] += GNSS_RATES[kind] * n
        if n < 2 * MIN_GAP_POINTS:
            return placed
        for kind in GNSS_TYPES:
            for _ in range(GNSS_TRIES):
                if self.budget[kind] <= 0:
                    break
                episode = self._draw(kind, t, east, north, step)
                if episode is None:
                    continue
                k = episode.stop - episode.start
                if self.budget[kind] < k / 2:
                    continue
                lo = max(episode.start - MIN_GAP_POINTS, 0)
                hi = min(episode.stop + MIN_GAP_POINTS, n)
                if busy[lo:hi].any():
                    continue
                busy[lo:hi] = True
                placed.append(episode)
                self.budget[kind] -= k
        placed.sort(key=lambda e: e.start)
        return placed

    def _draw(
        self,
        kind: str,
        t: np.ndarray,
        east: np.ndarray,
        north: np.ndarray,
        step: np.ndarray,
    ) -> _GnssEpisode | None:
        """One episode of ``kind`` at a random place; ``None`` when the draw does not fit."""
        rng = self.rng
        n = t.size
        start = int(rng.integers(1, n))
        if kind == "drift":
            seconds = float(rng.uniform(*DRIFT_S))
            rate = float(rng.uniform(*DRIFT_RATE_MPS)) * self.scale
            angle = float(rng.uniform(0.0, 2.0 * np.pi))
            hold = bool(rng.random() < DRIFT_HOLD_PROBABILITY)
            if hold:
                held = float(rng.uniform(*DRIFT_HOLD_S))
                start = int(np.searchsorted(t, t[-1] - held - seconds, side="left"))
                stop = n
            else:
                stop = _span(t, start, seconds)
            if start < 1 or stop - start < 1 or (not hold and stop >= n):
                return None
            grown = rate * np.minimum(t[start:stop] - t[start - 1], seconds)
            return _GnssEpisode(
                "drift",
                start,
                stop,
                "permanent" if hold else "transient",
                grown * np.sin(angle),
                grown * np.cos(angle),
            )
        if kind == "freeze":
            stop = _span(t, start - 1, float(rng.uniform(*FREEZE_S)))
            if stop - start < 1 or stop >= n:
                return None
            moved = np.hypot(
                east[start:stop] - east[start - 1], north[start:stop] - north[start - 1]
            )
            if (
                _too_slow_to_freeze(step, start - 1, slice(start - 1, stop - 1))
                or not (moved > 0).all()
            ):
                return None
            zero = np.zeros(stop - start)
            return _GnssEpisode("freeze", start, stop, "transient", zero, zero)
        if kind == "multipath":
            stop = _span(t, start, float(rng.uniform(*MULTIPATH_S)))
            if stop - start < 1 or stop >= n:
                return None
            tau = float(rng.uniform(*MULTIPATH_TAU_S))
            k = stop - start
            rho = np.exp(-np.r_[0.0, np.diff(t[start:stop])] / tau)
            shocks = rng.standard_normal((2, k))
            latent = np.empty((2, k))
            latent[:, 0] = shocks[:, 0]
            for i in range(1, k):
                latent[:, i] = rho[i] * latent[:, i - 1] + np.sqrt(1.0 - rho[i] ** 2) * shocks[:, i]
            lo, hi = MULTIPATH_M
            size = (lo + (hi - lo) * _std_normal_cdf(latent[0])) * self.scale
            heading = float(rng.uniform(0.0, 2.0 * np.pi)) + MULTIPATH_TURN_RAD * (
                2.0 * _std_normal_cdf(latent[1]) - 1.0
            )
            return _GnssEpisode(
                "multipath",
                start,
                stop,
                "transient",
                size * np.sin(heading),
                size * np.cos(heading),
            )
        stop = _span(t, start, float(rng.uniform(*OUTAGE_S)))
        if stop - start < 1 or stop >= n:
            return None
        zero = np.zeros(stop - start)
        missing = bool(rng.random() < OUTAGE_MISSING_PROBABILITY)
        return _GnssEpisode("outage", start, stop, "transient", zero, zero, missing)


def _receiver_columns(cmap: ColumnMap) -> dict[str, str]:
    """Input column for each of :data:`QUALITY_COLUMNS`, found as :func:`to_fixes` finds
    them (its canonical name where the input has none)."""
    found = {"fix_quality": cmap.fix_quality, "satellites": cmap.satellites, "hdop": cmap.hdop}
    return {role: col if col is not None else role for role, col in found.items()}


def inject_gnss(
    table: pd.DataFrame, *, seed: int, scale: float = 1.0, columns: ColumnMap | None = None
) -> pd.DataFrame:
    """Corrupt positions with protocol ``gnss``; return the table with labels appended.

    Protocol ``grad``'s episodes (noise and jump; transient, intermittent,
    permanent; same shapes, rates and per-channel labels) plus the faults
    real receivers make, on both channels at once (see ``docs/protocols.md``
    for every rate and range):

    ``freeze``
        the fix repeats the last value for 3-60 s while the vehicle moves;
    ``drift``
        an offset growing at 0.2-3 m/s in a random direction for 20-300 s,
        then snapping back (time type ``transient``) or holding its final
        offset to the end of the track (``permanent``): a spoofing take-over;
    ``multipath``
        offsets of 10-80 m for 2-20 s, AR(1)-correlated over 2-20 s;
    ``outage``
        for 1-30 s the receiver reports no fix (``fix_quality`` 0,
        ``satellites`` 0, ``hdop`` 99.99, written into the input's own
        receiver-quality columns, added where it has none) and the position
        is frozen at the last fix or missing.

    The added types are placed first (their own point budgets), ``grad``'s
    around them, with at least 10 normal fixes between any two episodes of a
    channel. Columns as :func:`inject_grad`'s, the bias types extended,
    plus ``label_episode`` (the episode that decides the row's labels, -1
    for none) and ``label_offset_m`` (distance of the written position from
    the truth in metres, NaN where it is missing). Speed, heading and every
    other column are left true. Same input and seed, same bytes.
    """
    _check_scale(scale)
    fixes, cmap, lat_true, lon_true = _truth(table, columns)
    n = len(fixes)
    t_all = fixes["t"].to_numpy(dtype=np.float64)
    lat = lat_true.copy()
    lon = lon_true.copy()
    offset_m = np.zeros(n)
    outage = np.zeros(n, dtype=bool)
    labels = {name: _Channel.empty(n) for name in ("lat", "lon")}
    rng = np.random.default_rng(seed)
    scheduler = _GradScheduler(rng, scale)
    gnss = _GnssScheduler(rng, scale)
    for rows in track_rows(fixes, invalid_reasons(fixes) == ""):
        frame = LocalFrame(float(lat_true[rows[0]]), float(lon_true[rows[0]]))
        east, north = frame.to_local(lat_true[rows], lon_true[rows])
        base = _Channel.empty(rows.size)
        de, dn = np.zeros(rows.size), np.zeros(rows.size)
        for episode in gnss.track(t_all[rows], east, north):
            span = slice(episode.start, episode.stop)
            at = rows[span]
            base.time_type[span] = episode.time_type
            base.bias_type[span] = episode.kind
            base.episode[span] = scheduler.next_episode
            scheduler.next_episode += 1
            if episode.kind in ("freeze", "outage"):
                # The last fix repeated exactly, or (an outage) no position at all.
                ref = rows[episode.start - 1]
                lat[at], lon[at] = lat_true[ref], lon_true[ref]
                de[span] = east[episode.start - 1] - east[span]
                dn[span] = north[episode.start - 1] - north[span]
                outage[at] = episode.kind == "outage"
                if episode.missing:
                    lat[at], lon[at] = np.nan, np.nan
                    de[span], dn[span] = np.nan, np.nan
            else:
                de[span], dn[span] = episode.east, episode.north
                lat[at], lon[at] = frame.to_geodetic(east[span] + de[span], north[span] + dn[span])
        for name in ("lat", "lon"):
            own = _Channel(
                base.offset_m.copy(),
                base.time_type.copy(),
                base.bias_type.copy(),
                base.episode.copy(),
            )
            ch = scheduler.channel(name, rows.size, own)
            # grad's faults, written one channel at a time exactly as inject_grad writes them.
            hit = (ch.episode >= 0) & (base.episode < 0)
            coords = {"lat": lat, "lon": lon}
            _write_channel(name, ch, hit, rows, frame, east, north, coords, labels[name])
            (dn if name == "lat" else de)[hit] = ch.offset_m[hit]
        offset_m[rows] = np.hypot(de, dn)

    la, lo = labels["lat"], labels["lon"]
    use_lon = _rank(lo.time_type, lo.bias_type) > _rank(la.time_type, la.bias_type)
    result = table.reset_index(drop=True).copy()
    # In the column's own unit (degrees, or degrees x 1e7 for a latitudeE7).
    result[cmap.lat] = lat * units_per_degree(cmap.lat)
    result[cmap.lon] = lon * units_per_degree(cmap.lon)
    quality = _receiver_columns(cmap)
    for role, value in (
        ("fix_quality", OUTAGE_FIX_QUALITY),
        ("satellites", OUTAGE_SATELLITES),
        ("hdop", OUTAGE_HDOP),
    ):
        col = quality[role]
        if col in result.columns:  # the input's own column, its other values as they were
            if outage.any():
                result[col] = result[col].where(~outage, value)
        else:
            result[col] = np.where(outage, float(value), np.nan)
    _write_labels(result, labels, use_lon)
    result["label_episode"] = np.where(use_lon, lo.episode, la.episode)
    result["label_offset_m"] = offset_m
    result["lat_true"] = lat_true
    result["lon_true"] = lon_true
    return result


def gnss_rates(labelled: pd.DataFrame) -> pd.DataFrame:
    """Achieved shares of protocol ``gnss``: percent of all rows and episodes per bias type.

    Rows: every bias type (``grad``'s noise and jump, then :data:`GNSS_TYPES`)
    and ``total``; columns ``rows`` (percent of rows whose combined label is
    that type) and ``episodes`` (how many episodes decide some row's label).
    """
    n = max(len(labelled), 1)
    bias = labelled["label_bias"].to_numpy(dtype=object)
    episode = labelled["label_episode"].to_numpy(dtype=np.int64)
    table: dict[str, dict[str, float]] = {}
    for kind in (*BIAS_TYPES, *GNSS_TYPES, "total"):
        sel = (bias != "none") if kind == "total" else (bias == kind)
        table[kind] = {
            "rows": 100.0 * float(np.sum(sel)) / n,
            "episodes": float(np.unique(episode[sel & (episode >= 0)]).size),
        }
    return pd.DataFrame.from_dict(table, orient="index")


# --------------------------------------------------------- protocol sensor-grid

SENSOR_START_PROBABILITY = 0.05
#: How a ``constant`` fault is written: ``stuck`` (default) holds the reading at
#: ``x(t0) + u`` for the episode; ``offset`` adds ``u`` to every reading of the
#: episode (``x + u``), the additive reading of the source papers' injection.
CONSTANT_MODES = ("stuck", "offset")
INSTANT_SIGMA = 0.1  # N(0, 0.01) read as variance 0.01


@dataclass(frozen=True)
class SensorFaultRow:
    """One row of the comparison table: a fault type with its magnitude and duration.

    ``magnitude`` is M for *instant* (offset M·e, e ~ N(0, 0.1²)) and the
    upper bound ``a`` of U(0, a) or of the drift ramp otherwise; ``duration``
    is in time steps.
    """

    name: str
    kind: str
    magnitude: float
    duration: int


def _rows() -> tuple[SensorFaultRow, ...]:
    rows = [
        SensorFaultRow(f"instant-{m}", "instant", float(m), 1) for m in (25, 100, 500, 1000, 10000)
    ]
    for kind in ("constant", "bias"):
        rows += [
            SensorFaultRow(f"{kind}-{a}-{d}", kind, float(a), d)
            for a, d in ((5, 3), (5, 5), (5, 10), (3, 10), (1, 10))
        ]
    rows += [
        SensorFaultRow(f"drift-{a}-{d}", "drift", float(a), d)
        for a, d in ((4, 10), (4, 20), (2, 10), (2, 20))
    ]
    return tuple(rows)


#: The 19 rows of the paper's comparison table, in its order.
SENSOR_GRID_ROWS = _rows()


def sensor_grid_row(name: str) -> SensorFaultRow | None:
    """The row called ``name``; ``None`` for ``"mixed"``; ConfigError for anything else."""
    if name == "mixed":
        return None
    for row in SENSOR_GRID_ROWS:
        if row.name == name:
            return row
    known = ", ".join([r.name for r in SENSOR_GRID_ROWS] + ["mixed"])
    raise ConfigError(f"unknown sensor-grid row {name!r}; known rows: {known}")


def with_accel_mps2(table: pd.DataFrame) -> pd.DataFrame:
    """``table`` with longitudinal acceleration in m/s² as ``accel_x_mps2`` (from ``accel_x_g``).

    Returned unchanged when it already has ``accel_x_mps2`` or lacks ``accel_x_g``.
    """
    if "accel_x_mps2" in table.columns or "accel_x_g" not in table.columns:
        return table
    out = table.copy()
    out["accel_x_mps2"] = pd.to_numeric(out["accel_x_g"], errors="coerce") * GRAVITY
    return out


def with_fix_speed(table: pd.DataFrame, columns: ColumnMap | None = None) -> pd.DataFrame:
    """``table`` with ``speed_fix_mps``: the speed derived from the fixes, beside the reported one.

    Per track in time order, the distance (in the track's tangent plane) from the
    previous usable fix divided by the time step (m/s): a second, independent
    speed source like the GPS speed beside the wheel speed in SPMD. The first
    fix of a track, a repeated time stamp and unusable rows get NaN. Under
    ``sensor-grid`` the positions are never corrupted, so this channel is a
    clean reference; it is computed before injection and never faulty.
    Returned unchanged when the column is already there.
    """
    if "speed_fix_mps" in table.columns:
        return table
    fixes = to_fixes(table, columns)
    lat = fixes["lat"].to_numpy(dtype=np.float64)
    lon = fixes["lon"].to_numpy(dtype=np.float64)
    t = fixes["t"].to_numpy(dtype=np.float64)
    out_speed = np.full(len(fixes), np.nan)
    for rows in track_rows(fixes, invalid_reasons(fixes) == ""):
        if rows.size < 2:
            continue
        frame = LocalFrame(float(lat[rows[0]]), float(lon[rows[0]]))
        east, north = frame.to_local(lat[rows], lon[rows])
        dt = np.diff(t[rows])
        with np.errstate(divide="ignore", invalid="ignore"):
            v = np.hypot(np.diff(east), np.diff(north)) / dt
        out_speed[rows[1:]] = np.where(dt > 0, v, np.nan)
    result = table.copy()
    result["speed_fix_mps"] = out_speed
    return result


def _check_sensor_columns(table: pd.DataFrame, speed_col: str | None, source: str) -> None:
    if speed_col is None:
        raise InputError(
            "protocol sensor-grid needs a speed column (m/s)",
            source=source,
            hint="name it with --speed-col",
        )
    for col in ("accel_x_mps2", "gyro_z_dps"):
        if col not in table.columns:
            raise InputError(
                f"protocol sensor-grid needs column {col!r}",
                source=source,
                hint="it corrupts speed, longitudinal acceleration (accel_x_g in g or accel_x_mps2) "
                "and yaw rate (gyro_z_dps), as in the DrivePlotR drives",
            )


def _sensor_fault(
    truth: np.ndarray,
    row: SensorFaultRow,
    rng: np.random.Generator,
    scale: float,
    constant: str = "stuck",
) -> np.ndarray:
    """The corrupted values of one episode of ``row`` over the true readings ``truth``."""
    if row.kind == "instant":
        return truth + row.magnitude * scale * rng.normal(0.0, INSTANT_SIGMA, size=truth.size)
    if row.kind == "constant":
        u = rng.uniform(0.0, row.magnitude * scale)
        return truth + u if constant == "offset" else np.full(truth.size, truth[0] + u)
    if row.kind == "bias":
        return truth + rng.uniform(0.0, row.magnitude * scale)
    ramp = np.linspace(0.0, row.magnitude * scale, row.duration)
    return truth + ramp[: truth.size]


def inject_sensor_grid(
    table: pd.DataFrame,
    *,
    row: str,
    seed: int,
    scale: float = 1.0,
    columns: ColumnMap | None = None,
    constant: str = "stuck",
) -> pd.DataFrame:
    """Corrupt speed, acceleration and yaw rate with one sensor-grid row (or ``"mixed"``).

    Per track, in time order, each step outside an episode starts one with
    probability 0.05 on a channel chosen uniformly (one faulty channel at a
    time); ``"mixed"`` draws the type uniformly, then a row of that type, per
    episode. Episodes are cut at the end of a track. The corrupted values
    overwrite the speed column and ``gyro_z_dps``; acceleration is written to
    ``accel_x_mps2`` (added when the input has ``accel_x_g``, which is then
    overwritten with the corrupted value in g so no column leaks the truth).

    Appended: ``label_anomaly``, ``label_<channel>``, ``label_type``,
    ``label_episode`` and ``<channel>_true`` for channels ``speed_mps``,
    ``accel_x_mps2``, ``gyro_z_dps``. Every step of an episode is labelled,
    including draws that happen to change nothing (a drift's first step, a
    constant fault equal to the reading). ``constant`` is ``"stuck"`` (the
    reading held at ``x(t0) + u``) or ``"offset"`` (``x + u`` over the
    episode), see :data:`CONSTANT_MODES`.
    """
    _check_scale(scale)
    if constant not in CONSTANT_MODES:
        raise ConfigError(
            f"constant fault mode must be one of {', '.join(CONSTANT_MODES)}, got {constant!r}"
        )
    fault = sensor_grid_row(row)
    source = str(table.attrs.get("source", "<data>"))
    in_g = "accel_x_mps2" not in table.columns and "accel_x_g" in table.columns
    table = with_accel_mps2(table)
    fixes = to_fixes(
        table, columns, channels=[c for c in SENSOR_CHANNELS[1:] if c in table.columns]
    )
    cmap: ColumnMap = fixes.attrs["columns"]
    _check_sensor_columns(table, cmap.speed, source)
    assert cmap.speed is not None
    truth = {
        "speed_mps": fixes["speed"].to_numpy(dtype=np.float64),
        "accel_x_mps2": fixes["accel_x_mps2"].to_numpy(dtype=np.float64),
        "gyro_z_dps": fixes["gyro_z_dps"].to_numpy(dtype=np.float64),
    }
    values = {k: v.copy() for k, v in truth.items()}
    n = len(fixes)
    channel_of = np.full(n, -1, dtype=np.int64)
    kind = np.full(n, "none", dtype=object)
    episode = np.full(n, -1, dtype=np.int64)
    rng = np.random.default_rng(seed)
    usable = np.isfinite(fixes["t"].to_numpy(dtype=np.float64))
    next_id = 0
    for rows in track_rows(fixes, usable):
        step = 0
        while True:
            step += int(rng.geometric(SENSOR_START_PROBABILITY)) - 1
            if step >= rows.size:
                break
            channel = int(rng.integers(len(SENSOR_CHANNELS)))
            this = fault if fault is not None else _mixed_row(rng)
            end = min(step + this.duration, rows.size)
            name = SENSOR_CHANNELS[channel]
            span = rows[step:end]
            values[name][span] = _sensor_fault(truth[name][span], this, rng, scale, constant)
            channel_of[span] = channel
            kind[span] = this.kind
            episode[span] = next_id
            next_id += 1
            step = end

    result = table.reset_index(drop=True).copy()
    result[cmap.speed] = values["speed_mps"]
    result["gyro_z_dps"] = values["gyro_z_dps"]
    result["accel_x_mps2"] = values["accel_x_mps2"]
    if in_g:
        result["accel_x_g"] = values["accel_x_mps2"] / GRAVITY
    result["label_anomaly"] = (episode >= 0).astype(np.int8)
    for i, name in enumerate(SENSOR_CHANNELS):
        result[f"label_{name}"] = (channel_of == i).astype(np.int8)
    result["label_type"] = kind
    result["label_episode"] = episode
    for name in SENSOR_CHANNELS:
        result[f"{name}_true"] = truth[name]
    return result


def _mixed_row(rng: np.random.Generator) -> SensorFaultRow:
    kind = SENSOR_TYPES[int(rng.integers(len(SENSOR_TYPES)))]
    rows = [r for r in SENSOR_GRID_ROWS if r.kind == kind]
    return rows[int(rng.integers(len(rows)))]


def sensor_grid_rates(labelled: pd.DataFrame) -> pd.DataFrame:
    """Achieved shares (percent of all rows): rows fault types and ``total``, columns channels and ``all``."""
    n = max(len(labelled), 1)
    kinds = labelled["label_type"].to_numpy(dtype=object)
    table: dict[str, dict[str, float]] = {}
    for kind in (*SENSOR_TYPES, "total"):
        sel = (kinds != "none") if kind == "total" else (kinds == kind)
        row = {
            ch: 100.0 * float(np.sum(sel & (labelled[f"label_{ch}"].to_numpy() == 1))) / n
            for ch in SENSOR_CHANNELS
        }
        row["all"] = 100.0 * float(np.sum(sel)) / n
        table[kind] = row
    return pd.DataFrame.from_dict(table, orient="index")


#: m/s: a hold starts only on a vehicle this fast. Freezing at 10 m/s is a
#: "stop" within one step, 5 m/s² or more at 0.5 Hz and beyond any car's
#: braking at 1 Hz and faster; a hold on a slower car is indistinguishable
#: from it braking to a stop until the hold ends, and a label no causal
#: detector can earn only teaches a model to flag every stop. (The simulator's
#: hard stops, up to 7 m/s², reach a pinned fix after a step of up to ~11 m/s
#: at 0.5 Hz: a few honest look-alikes, labelled normal.)
_FREEZE_ONSET_SPEED = 10.0


def inject_freeze(
    labelled: pd.DataFrame,
    *,
    seed: int,
    share: float = 0.02,
    hold_s: tuple[float, float] = (3.0, 60.0),
    stale_start: float = 0.1,
    stale_offset_m: tuple[float, float] = (30.0, 500.0),
    columns: ColumnMap | None = None,
) -> pd.DataFrame:
    """Add *frozen fixes* to a labelled table (protocol ``grad`` output): a receiver
    repeating its last solution while the vehicle moves on.

    Two shapes a GNSS receiver really produces (see the Munich and Austin
    drives in ``../shared/data``): a **hold** inside a drive (tunnel, lost
    lock: the last fix repeats for ``hold_s`` seconds, then the position jumps
    to where the vehicle is), and a **stale start** (probability
    ``stale_start`` per track: the first fixes repeat a position from before,
    ``stale_offset_m`` away, until the first real fix). Held fixes are
    labelled ``label_anomaly = 1`` with bias ``freeze`` (time type
    ``transient``); the jump back to the truth is *not* a fault. A stale
    start's held fixes also get ``label_stale = 1`` (0 elsewhere): until the
    jump no causal detector can tell them from a parked car, so training
    does not count them (:mod:`gradgps._train.labels`). Holds are
    placed where the vehicle moves at :data:`_FREEZE_ONSET_SPEED` (10 m/s) or
    more when the fix freezes and at 2 m/s or more for most of the hold (a frozen fix of a parked or crawling car is a true
    fix, and a hold that starts as the car brakes to a stop is a real stop) and only on fixes without a label, about ``share`` of each track's
    fixes. Seeded: the same input and seed give the same bytes.
    """
    if not (0 <= share < 1 and 0 <= stale_start <= 1):
        raise ConfigError(
            f"share must be in [0, 1) and stale_start in [0, 1], got {share}, {stale_start}"
        )
    fixes = to_fixes(labelled, columns)
    cmap: ColumnMap = fixes.attrs["columns"]
    assert cmap.lat is not None
    assert cmap.lon is not None
    rng = np.random.default_rng(seed)
    result = labelled.copy()
    lat = fixes["lat"].to_numpy(dtype=np.float64).copy()
    lon = fixes["lon"].to_numpy(dtype=np.float64).copy()
    anomaly = result["label_anomaly"].to_numpy().astype(np.int8).copy()
    bias = result["label_bias"].to_numpy(dtype=object).copy()
    time_type = result["label_time"].to_numpy(dtype=object).copy()
    stale = np.zeros(len(result), np.int8)
    t_all = fixes["t"].to_numpy(dtype=np.float64)
    for rows in track_rows(fixes, invalid_reasons(fixes) == ""):
        if rows.size < 10:
            continue
        t = t_all[rows]
        frame = LocalFrame(float(lat[rows[0]]), float(lon[rows[0]]))
        east, north = frame.to_local(lat[rows], lon[rows])
        step_speed = _step_speeds(t, east, north)
        free = anomaly[rows] == 0
        if rng.random() < stale_start:
            end = int(np.searchsorted(t, t[0] + rng.uniform(*hold_s)))
            end = min(max(end, 2), rows.size - 5)
            if free[: end + 1].all():
                angle = rng.uniform(0, 2 * np.pi)
                dist = rng.uniform(*stale_offset_m)
                s_lat, s_lon = frame.to_geodetic(
                    east[end] + dist * np.sin(angle), north[end] + dist * np.cos(angle)
                )
                held = rows[:end]
                lat[held], lon[held] = s_lat, s_lon
                anomaly[held], bias[held], time_type[held] = 1, "freeze", "transient"
                stale[held] = 1
                free[:end] = False
        budget = share * rows.size
        tries = 0
        while budget > 0 and tries < 50:
            tries += 1
            start = int(rng.integers(1, rows.size - 3))
            stop = int(np.searchsorted(t, t[start] + rng.uniform(*hold_s)))
            stop = min(stop, rows.size - 1)
            span = slice(start + 1, stop)
            # The vehicle must be moving when the fix freezes and for most of the
            # hold (else the hold is a real stop), and one clean fix must follow it.
            if (
                stop - start < 2
                or not free[start : stop + 1].all()
                or _too_slow_to_freeze(step_speed, start, span)
            ):
                continue
            held = rows[span]
            lat[held], lon[held] = lat[rows[start]], lon[rows[start]]
            anomaly[held], bias[held], time_type[held] = 1, "freeze", "transient"
            free[max(start - 5, 0) : stop + 5] = False
            budget -= stop - start - 1
    # In the column's own unit (degrees, or degrees x 1e7 for a latitudeE7).
    result[cmap.lat] = lat * units_per_degree(cmap.lat)
    result[cmap.lon] = lon * units_per_degree(cmap.lon)
    result["label_anomaly"] = anomaly
    result["label_bias"] = bias
    result["label_time"] = time_type
    result["label_stale"] = stale
    return result

"""A seeded car-drive simulator: the project's embedded default data.

``make demo`` and the shipped default model train and run on simulated
drives, so the simulator has to look like a real vehicle GPS log where it
matters to a fault detector (step lengths, speeds, accelerations, heading
changes, stops, the shape of the position error) while needing no files,
being reproducible to the byte and fast (1,000 ten-minute tracks at 1 Hz in a
few seconds). ``docs/simulator.md`` compares its statistics with the real
DrivePlotR drives and lists where every default comes from.

How a drive is made (all in NumPy, one track at a time):

1. **Route** (:func:`_plan_route`): a chain of *legs* of a road class (urban,
   arterial, highway; the mix differs per track). A leg is a series of
   straights joined by gentle curves and, off the highway, intersections:
   drive through, traffic light (red: stop and wait), stop sign (stop 1-4 s),
   or a ~90 degree turn of small radius; a few stops are long (queues) and a
   few are braked into hard. Highway legs are entered and left by
   a ramp curve. The route is a curvature profile ``kappa(s)`` on a 1 m grid
   along the path, box-smoothed so curvature ramps linearly in and out of
   every curve (a clothoid transition, as roads are built).
2. **Speed profile** (:func:`_speed_profile`): the speed cap at each metre is
   the road's limit times a per-track driver factor and the lateral-acceleration
   limit ``sqrt(a_lat / |kappa|)``; stops pin it to 0. A forward pass bounds
   acceleration and a backward pass bounds braking (both exact cumulative
   minima of ``v^2``, so vectorised). The resulting time history is then
   box-filtered over ``T = (a_max + b_max) / jerk_max`` seconds, which bounds
   jerk by ``jerk_max`` while keeping ``|a|`` within the limits (a hard stop
   brakes beyond ``b_max`` and so with a higher jerk, as a real one); the caps
   are eroded beforehand by the distance the smoothing can shift a speed, so
   the lateral limit still holds after smoothing.
3. **Sensors** (:func:`_measure`): GNSS position = truth + a first-order
   Gauss-Markov error per axis (metres, slowly varying) + white noise scaled
   by a simulated HDOP; speed and heading come from a noisy velocity vector
   (so heading noise grows as ``1/speed`` and is uniform when stopped);
   receivers in *static hold* freeze position, zero speed and hold heading at
   some stops, from the moment the car rolls slower than the receiver's
   threshold (0.3-1.5 m/s, per track) until it rolls faster again; optional IMU longitudinal acceleration (with the gravity
   component of the road grade) and yaw rate, each with a per-track bias and
   white noise.

Randomness: every track draws from ``numpy.random.default_rng(SeedSequence(
[seed, track]))`` in a fixed order (stop styles from a stream spawned off it), so a track is a pure function of
``(seed, track, minutes, rate_hz, origin, params)``; the IMU draws happen even
when ``imu=False`` so the GNSS columns do not depend on that switch.
Time starts at :data:`EPOCH` (2023-11-14 22:13:20 UTC) for every track.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, fields

import numpy as np
import pandas as pd
from numpy.typing import NDArray

from .._exceptions import ConfigError
from .._tracks.geo import LocalFrame

__all__ = [
    "DEFAULT_ORIGIN",
    "EPOCH",
    "SimulatorParams",
    "simulate_drive",
    "simulate_fleet",
]

FloatArray = NDArray[np.float64]

EPOCH = 1_700_000_000.0
"""Unix time of every simulated track's first fix: 2023-11-14 22:13:20 UTC."""

DEFAULT_ORIGIN = (41.2565, -95.9345)
"""Omaha, Nebraska: where the real DrivePlotR drives the simulator is compared with were logged."""

_GRAVITY = 9.80665
_DS = 1.0  # metres between route grid nodes
_FINE_DT = 0.1  # seconds: at most this between samples of the true motion
_URBAN, _ARTERIAL, _HIGHWAY = 0, 1, 2
_HARD_STOP_M = 150.0  # metres before a hard stop braked at SimulatorParams.hard_stop_decel


@dataclass(frozen=True)
class SimulatorParams:
    """Every tunable of the simulator, with its unit; defaults are documented in docs/simulator.md.

    Defaults marked *datasheet* come from consumer GNSS receiver or MEMS IMU
    specifications, *road* from road design practice, and *chosen* values are
    ours, tuned so the statistics match the real DrivePlotR drives (1 Hz,
    Omaha, 2019). Ranges are ``(low, high)`` of a uniform draw.
    """

    # --- roads and driving -------------------------------------------------
    urban_speed_limit: float = 13.4
    """m/s (30 mph, US urban default)."""
    arterial_speed_limit: float = 20.1
    """m/s (45 mph)."""
    highway_speed_limit: float = 31.3
    """m/s (70 mph, Iowa/Nebraska interstates)."""
    driver_speed_factor: tuple[float, float] = (0.95, 1.15)
    """Per-track multiplier on limits (chosen: free-flow speeds scatter around the limit)."""
    max_accel: float = 2.5
    """m/s^2, hardest acceleration from standstill (chosen: the real drives' p99 speed change at low speed is 2-3 m/s^2)."""
    accel_fade_speed: float = 45.0
    """m/s: acceleration and braking limits scale by ``1 - v / accel_fade_speed`` (chosen: the real drives' p99 speed change falls from ~2.2 m/s^2 below 15 m/s to ~0.8 above 25 m/s)."""
    accel_fade_floor: float = 0.2
    """Smallest factor that scaling can reach (chosen)."""
    max_decel: float = 3.4
    """m/s^2, hardest normal braking (road: ITE/AASHTO comfortable deceleration 3.4 m/s^2)."""
    accel_use: tuple[float, float] = (0.3, 1.0)
    """Per-leg fraction of the limits actually used (chosen: drivers vary)."""
    max_jerk: float = 2.5
    """m/s^3 (chosen within the 1-3 m/s^3 comfort range reported for passenger cars)."""
    max_lateral_accel: float = 3.0
    """m/s^2 in curves (chosen: 99.9th percentile of the real drives' lateral acceleration)."""
    turn_radius: tuple[float, float] = (8.0, 20.0)
    """m, intersection turns (road: urban corner radii 5-15 m plus lane offset)."""
    urban_curve_radius: tuple[float, float] = (60.0, 400.0)
    """m, gentle bends on urban streets (chosen)."""
    arterial_curve_radius: tuple[float, float] = (150.0, 800.0)
    """m (road: AASHTO minimum ~200 m at 45 mph)."""
    highway_curve_radius: tuple[float, float] = (600.0, 2500.0)
    """m (road: AASHTO minimum ~600 m at 70 mph)."""
    ramp_radius: tuple[float, float] = (60.0, 150.0)
    """m, highway ramps (road)."""
    red_light_wait: tuple[float, float] = (5.0, 90.0)
    """s waited at a red light (chosen: real stops last 1-80 s, median ~15 s)."""
    stop_sign_wait: tuple[float, float] = (1.0, 4.0)
    """s stopped at a stop sign (chosen)."""
    long_stop_probability: float = 0.05
    """Chance that a stop on the way (not the start) is a long one (chosen, see :attr:`long_stop_wait`)."""
    long_stop_wait: tuple[float, float] = (90.0, 300.0)
    """s, a long stop's wait: queues, level crossings, drop-offs.

    Why: lights and signs alone never stop a simulated car over ~90 s, but
    the real train/validation drives do (longest stop: Austin 93-104 s,
    Nevada 240-316 s, DrivePlotR 349-522 s; Nevada's p90 is ~220 s). A
    detector that only saw short stops may take a long pinned fix for a
    frozen receiver.
    """
    idle: tuple[float, float] = (5.0, 40.0)
    """s idling before the start (chosen)."""
    transition_length: float = 6.0
    """m over which curvature ramps in and out of a curve (chosen, a short clothoid)."""
    speed_wander: float = 0.07
    """Std of the slowly varying fraction by which a driver's wanted speed departs from the limit (chosen: real speeds fluctuate by a few m/s at cruise)."""
    curvature_wander: float = 3e-4
    """1/m std of small bends and lane-keeping wander added to every road (chosen: real heading changes ~0.3 deg/s at highway speed)."""
    wander_length: float = 150.0
    """m, correlation length of both wanders (chosen)."""
    # --- GNSS ----------------------------------------------------------------
    gnss_correlated_sigma: float = 1.5
    """m per axis, std of the Gauss-Markov error (datasheet: CEP 2.0-2.5 m = 1.7-2.1 m per axis; lowered a little for a good-sky-view logger)."""
    gnss_correlation_time: float = 300.0
    """s, time constant of that error (datasheet/literature: tens to hundreds of seconds; chosen to match the real position residuals)."""
    gnss_white_sigma: float = 0.1
    """m per axis at the median HDOP, scale of the epoch-to-epoch noise (chosen: receiver filtering leaves under a decimetre, matching the real residuals)."""
    gnss_white_dof: float = 2.5
    """Degrees of freedom of the Student-t epoch noise (chosen: multipath gives heavier tails than Gaussian; the real residuals' p99/median is ~9)."""
    velocity_sigma: float = 0.1
    """m/s per axis, Doppler velocity noise (datasheet: u-blox M8 0.05 m/s in open sky; doubled by us to match the real heading noise at low speed)."""
    static_hold_speed: float = 0.3
    """m/s, the lowest speed below which a receiver in static hold pins its position (datasheet: u-blox static-hold threshold, configurable)."""
    static_hold_speed_max: float = 1.5
    """m/s, the highest such threshold; each track's receiver draws its own between the two.

    Why (figures: ``python benchmarks/stop_stats.py real`` and ``sim``): real
    loggers pin the fix while the car still rolls. The Austin 2006
    logger's train/validation stops reach their first repeated fix after a
    last step of 1.4-5.5 m/s (p10-p90, 1 Hz), the NL phones' and DrivePlotR's
    after 1-2.8 m/s, while a single 0.3 m/s threshold gave the simulator
    1.1-2.2 m/s and never more than 3.5. Pinning early also makes the first
    step after the stop a catch-up step when the hold lets go (Austin: 11-26 %
    of exits are 2 m/s longer than the step after). datasheet: u-blox
    ``staticHoldThresh`` is 0-2.55 m/s; SiRF static navigation ~1.2 m/s.
    """
    static_hold_probability: float = 0.7
    """Chance that a given stop is in static hold (chosen to match the real share of zero-length steps)."""
    hard_stop_probability: float = 0.1
    """Chance that a stop is braked into hard (chosen, see :attr:`hard_stop_decel`)."""
    hard_stop_decel: tuple[float, float] = (4.0, 7.0)
    """m/s^2, braking on the last :data:`_HARD_STOP_M` metres before a hard stop (before the speed fade).

    Why: :attr:`max_decel` is comfortable braking, but real drives also halt
    hard (late at a light, a car ahead): fix-derived deceleration over the 5 s
    before a stop exceeds 4 m/s^2 at 18-32 % of the Austin 2006 train/validation
    stops and 0-7 % of DrivePlotR's (max 6.6 m/s^2 in Austin validation),
    against 0-3 % in the simulator without it. A detector that never saw a
    hard halt onto a pinned fix reads one as a frozen receiver. Emergency
    braking of a passenger car reaches 8-9 m/s^2 (road: dry-pavement
    friction); the range stays below it, and the speed fade and the jerk
    smoothing lower what the fixes show (1 Hz fixes: up to ~6.5 m/s^2).
    """
    vertical_sigma: float = 2.5
    """m, std of the correlated altitude error (datasheet: vertical ~1.5x horizontal)."""
    hdop_median: float = 1.2
    """Median HDOP (chosen: the real drives' median is 1.17)."""
    hdop_log_sigma: float = 0.3
    """Std of log(HDOP) (chosen: real p90 ~2.0)."""
    hdop_correlation_time: float = 60.0
    """s (chosen: HDOP changes as satellites rise, set and are masked)."""
    hdop_min: float = 0.8
    """Lowest HDOP reported (the real drives' minimum is 0.81)."""
    road_grade_sigma: float = 0.02
    """Std of road grade per straight (road: grades rarely exceed 6 %)."""
    # --- IMU -----------------------------------------------------------------
    accel_noise_sigma: float = 0.05
    """m/s^2 white noise on longitudinal acceleration (datasheet: MEMS ~150-300 ug/sqrt(Hz), low-pass filtered)."""
    accel_bias_sigma: float = 0.1
    """m/s^2 per-track bias (mounting tilt of ~0.6 degrees; the real logger's is 0.14)."""
    gyro_noise_sigma: float = 0.05
    """deg/s white noise on yaw rate (datasheet: MEMS ~0.005-0.01 deg/s/sqrt(Hz) x bandwidth)."""
    gyro_bias_sigma: float = 0.1
    """deg/s per-track bias (datasheet: uncalibrated MEMS bias +-0.1-0.5 deg/s)."""
    origin_alt: float = 330.0
    """m, altitude of the start (the real drives' median)."""

    def __post_init__(self) -> None:
        for f in fields(self):
            value = getattr(self, f.name)
            values = value if isinstance(value, tuple) else (value,)
            for v in values:
                if not (isinstance(v, int | float) and math.isfinite(v) and v >= 0):
                    raise ConfigError(
                        f"SimulatorParams.{f.name} must be finite and >= 0, got {value!r}"
                    )
            if isinstance(value, tuple) and (len(value) != 2 or value[0] > value[1]):
                raise ConfigError(
                    f"SimulatorParams.{f.name} must be a (low, high) pair with low <= high, got {value!r}"
                )
        positive = (
            "urban_speed_limit",
            "arterial_speed_limit",
            "highway_speed_limit",
            "max_accel",
            "max_decel",
            "max_jerk",
            "accel_fade_speed",
            "max_lateral_accel",
            "gnss_correlation_time",
            "hdop_correlation_time",
            "hdop_median",
            "transition_length",
        )
        for name in positive:
            if getattr(self, name) <= 0:
                raise ConfigError(
                    f"SimulatorParams.{name} must be > 0, got {getattr(self, name)!r}"
                )
        if self.turn_radius[0] <= 0 or self.accel_use[0] <= 0 or self.driver_speed_factor[0] <= 0:
            raise ConfigError(
                "SimulatorParams: turn_radius, accel_use and driver_speed_factor must be > 0"
            )
        if self.static_hold_probability > 1 or self.accel_use[1] > 1:
            raise ConfigError("SimulatorParams: static_hold_probability and accel_use must be <= 1")
        if self.hard_stop_probability > 1 or self.long_stop_probability > 1:
            raise ConfigError(
                "SimulatorParams: hard_stop_probability and long_stop_probability must be <= 1"
            )
        if self.static_hold_speed_max < self.static_hold_speed:
            raise ConfigError("SimulatorParams: static_hold_speed_max must be >= static_hold_speed")

    @property
    def smoothing_time(self) -> float:
        """Seconds of the box filter on speed: jerk <= (max_accel + max_decel) / smoothing_time = max_jerk."""
        return (self.max_accel + self.max_decel) / self.max_jerk


# ---------------------------------------------------------------------------
# Route
# ---------------------------------------------------------------------------


@dataclass
class _Route:
    """A route on a uniform grid of ``_DS`` metres, plus its stops."""

    kappa: FloatArray  # 1/m at each node, positive = turning right (clockwise)
    limit: FloatArray  # m/s desired speed at each node (limit x driver factor)
    accel: FloatArray  # m/s^2 acceleration used at each node
    decel: FloatArray  # m/s^2 braking used at each node
    grade: FloatArray  # rise/run at each node
    stop_node: NDArray[np.int64]  # node index of each stop (first one: the start)
    stop_wait: FloatArray  # seconds stopped at each
    stop_hold: NDArray[np.bool_]  # receiver in static hold during that stop
    hold_speed: float  # m/s below which this track's receiver pins its fix at a held stop


def _plan_route(rng: np.random.Generator, duration: float, p: SimulatorParams) -> _Route:
    """Draw legs and their elements until the route surely lasts ``duration`` seconds.

    Each element is (length m, curvature 1/m, road class, stop wait s or -1).
    Time spent on an element is at least length / top speed, so stopping when
    the sum of those lower bounds plus waits reaches ``duration`` guarantees
    the speed profile is long enough.
    """
    limits = np.array([p.urban_speed_limit, p.arterial_speed_limit, p.highway_speed_limit])
    driver = rng.uniform(*p.driver_speed_factor)
    mix = rng.dirichlet([3.0, 1.5, 1.0])
    lengths: list[float] = []
    kappas: list[float] = []
    classes: list[int] = []
    accels: list[float] = []
    decels: list[float] = []
    grades: list[float] = []
    stop_at: list[int] = []  # element index a stop sits at the start of
    stop_wait: list[float] = []
    stop_wait.append(rng.uniform(*p.idle))
    stop_at.append(0)
    elapsed = stop_wait[0]
    road = int(rng.choice(3, p=mix))
    leg_accel = leg_decel = leg_grade = climbed = 0.0

    def add(length: float, kappa: float) -> None:
        nonlocal elapsed
        lengths.append(length)
        kappas.append(kappa)
        classes.append(road)
        accels.append(leg_accel)
        decels.append(leg_decel)
        grades.append(leg_grade)
        elapsed += length / (limits[road] * driver)

    def arc(radius_range: tuple[float, float], angle_deg: tuple[float, float]) -> None:
        radius = rng.uniform(*radius_range)
        angle = math.radians(rng.uniform(*angle_deg))
        add(radius * angle, rng.choice((-1.0, 1.0)) / radius)

    def stop(wait: float) -> None:
        nonlocal elapsed
        stop_at.append(len(lengths))
        stop_wait.append(wait)
        elapsed += wait

    margin = p.smoothing_time + 5.0
    while elapsed < duration + margin:
        previous = road
        road = int(rng.choice(3, p=mix))
        leg_accel = rng.uniform(*p.accel_use)
        leg_decel = rng.uniform(*p.accel_use)
        if (road == _HIGHWAY) != (previous == _HIGHWAY):
            arc(p.ramp_radius, (60.0, 120.0))  # on- or off-ramp
        leg_length = rng.uniform(*((400.0, 2000.0), (1000.0, 5000.0), (3000.0, 15000.0))[road])
        done = 0.0
        while done < leg_length and elapsed < duration + margin:
            # Grades lean back towards the start's altitude so long drives stay on plausible terrain.
            drift = -climbed / 2000.0
            leg_grade = float(np.clip(rng.normal(drift, p.road_grade_sigma), -0.06, 0.06))
            block = rng.uniform(*((80.0, 250.0), (200.0, 800.0), (500.0, 3000.0))[road])
            add(block, 0.0)
            climbed += block * leg_grade
            done += block
            if road == _HIGHWAY:
                if rng.random() < 0.5:
                    arc(p.highway_curve_radius, (5.0, 30.0))
                continue
            if rng.random() < 0.3:
                arc(
                    p.urban_curve_radius if road == _URBAN else p.arterial_curve_radius,
                    (10.0, 45.0),
                )
                continue
            kind = rng.choice(
                4, p=(0.35, 0.3, 0.1, 0.25) if road == _URBAN else (0.5, 0.3, 0.0, 0.2)
            )
            if kind == 1 and rng.random() < 0.5:  # traffic light, red
                stop(rng.uniform(*p.red_light_wait))
            elif kind == 2:  # stop sign
                stop(rng.uniform(*p.stop_sign_wait))
            elif kind == 3:  # turn, after a stop half of the time
                if rng.random() < 0.5:
                    stop(
                        rng.uniform(*p.red_light_wait)
                        if rng.random() < 0.5
                        else rng.uniform(*p.stop_sign_wait)
                    )
                arc(p.turn_radius, (80.0, 100.0))
    add(50.0, 0.0)  # room to come to the final stop
    hold = rng.random(len(stop_at)) < p.static_hold_probability
    # Stop style draws from a stream of its own, so everything else about a drive
    # (route, wander, sensor noise) stays what it was before hard stops existed.
    style = rng.spawn(1)[0]
    hold_speed = float(style.uniform(p.static_hold_speed, p.static_hold_speed_max))
    hard = style.random(len(stop_at)) < p.hard_stop_probability
    hard_decel = style.uniform(*p.hard_stop_decel, len(stop_at))
    long = style.random(len(stop_at)) < p.long_stop_probability
    long[0] = False  # the start keeps its idle time
    waits = np.where(long, style.uniform(*p.long_stop_wait, len(stop_at)), stop_wait)

    length_arr = np.asarray(lengths)
    ends = np.cumsum(length_arr)
    n_nodes = math.ceil(ends[-1] / _DS) + 1
    s = np.arange(n_nodes) * _DS
    element = np.minimum(np.searchsorted(ends, s, side="right"), len(lengths) - 1)
    width = max(1, round(p.transition_length / _DS))
    wander = _gauss_markov(rng, n_nodes, p.curvature_wander, p.wander_length, _DS)
    kappa = _box_mean(np.asarray(kappas)[element] + wander, width)
    wanted = np.exp(_gauss_markov(rng, n_nodes, p.speed_wander, p.wander_length, _DS))
    starts = np.concatenate([[0.0], ends[:-1]])
    stop_node = np.round(starts[np.asarray(stop_at)] / _DS).astype(np.int64)
    decel = p.max_decel * np.asarray(decels)[element]
    reach = round(_HARD_STOP_M / _DS)
    for node, b in zip(stop_node[hard], hard_decel[hard], strict=True):
        decel[max(0, node - reach) : node] = b
    return _Route(
        kappa=kappa,
        limit=limits[np.asarray(classes)][element] * driver * wanted,
        accel=p.max_accel * np.asarray(accels)[element],
        decel=decel,
        grade=np.asarray(grades)[element],
        stop_node=stop_node,
        stop_wait=waits,
        stop_hold=hold,
        hold_speed=hold_speed,
    )


def _box_mean(x: FloatArray, width: int) -> FloatArray:
    """Centred moving average over ``width`` samples, edges padded with the end values."""
    if width <= 1:
        return x.astype(np.float64, copy=True)
    left = width // 2
    padded = np.concatenate([np.full(left, x[0]), x, np.full(width - 1 - left, x[-1])])
    c = np.concatenate([[0.0], np.cumsum(padded)])
    return np.asarray((c[width:] - c[:-width]) / width, dtype=np.float64)


def _running_min(x: FloatArray, radius: int) -> FloatArray:
    """min(x[i - radius : i + radius + 1]) for every i, in O(n) (van Herk / Gil-Werman)."""
    if radius <= 0:
        return x.copy()
    w = 2 * radius + 1
    n = x.size
    blocks = -(-(n + 2 * radius) // w)
    padded = np.full(blocks * w, np.inf)
    padded[radius : radius + n] = x
    grid = padded.reshape(blocks, w)
    prefix = np.minimum.accumulate(grid, axis=1).ravel()
    suffix = np.minimum.accumulate(grid[:, ::-1], axis=1)[:, ::-1].ravel()
    i = np.arange(n)
    return np.minimum(suffix[i], prefix[i + w - 1])


def _running_min_reference(x: FloatArray, radius: int) -> FloatArray:
    """Plain-loop version of :func:`_running_min`, for tests."""
    n = x.size
    return np.array([x[max(0, i - radius) : i + radius + 1].min() for i in range(n)])


# ---------------------------------------------------------------------------
# Speed profile
# ---------------------------------------------------------------------------


def _speed_cap_squared(route: _Route, p: SimulatorParams) -> FloatArray:
    """Highest allowed v^2 at each node before smoothing (limits, curves, stops).

    The smoothing in :func:`_motion` averages speeds over ``T`` seconds, in
    which the car moves at most ``T`` times the fastest limit nearby; taking
    the minimum cap over that distance keeps the smoothed speed under the
    cap of wherever the car actually is.
    """
    curve = p.max_lateral_accel / np.maximum(np.abs(route.kappa), 1e-12)
    cap = np.minimum(route.limit**2, curve)
    t_smooth = p.smoothing_time
    fastest = float(route.limit.max())
    near_limit = -_running_min(-route.limit, math.ceil(t_smooth * fastest / _DS))
    # Radii rounded up to 5 m/s steps of speed: a few filter passes, never too little erosion.
    step = 5.0
    radius = np.ceil(t_smooth * step * np.ceil(near_limit / step) / _DS).astype(np.int64)
    eroded = np.empty_like(cap)
    for r in np.unique(radius):
        where = radius == r
        eroded[where] = _running_min(cap, int(r))[where]
    eroded[route.stop_node] = 0.0
    eroded[-1] = 0.0
    return eroded


def _speed_profile(cap2: FloatArray, accel: FloatArray, decel: FloatArray) -> FloatArray:
    """Fastest v^2 per node under ``cap2`` with the given accel/brake limits per node.

    Forward: v_i^2 = min(cap_i^2, v_{i-1}^2 + 2 a_i ds), which unrolls to
    A_i + min_{j<=i}(cap_j^2 - A_j) with A the running sum of 2 a ds: a
    cumulative minimum. Backward likewise for braking, applied to the forward
    result (so increases stay bounded too).
    """
    gain = np.concatenate([[0.0], np.cumsum(2.0 * accel[1:] * _DS)])
    forward = gain + np.minimum.accumulate(cap2 - gain)
    loss = np.concatenate([np.cumsum((2.0 * decel[:-1] * _DS)[::-1])[::-1], [0.0]])
    backward = loss + np.minimum.accumulate((forward - loss)[::-1])[::-1]
    return np.asarray(np.maximum(backward, 0.0), dtype=np.float64)


def _speed_profile_reference(cap2: FloatArray, accel: FloatArray, decel: FloatArray) -> FloatArray:
    """The two passes of :func:`_speed_profile` as plain loops, for tests."""
    v2 = cap2.copy()
    for i in range(1, v2.size):
        v2[i] = min(v2[i], v2[i - 1] + 2.0 * accel[i] * _DS)
    for i in range(v2.size - 2, -1, -1):
        v2[i] = min(v2[i], v2[i + 1] + 2.0 * decel[i] * _DS)
    return np.maximum(v2, 0.0)


def _distance_at(
    t: FloatArray, leave: FloatArray, cell_dt: FloatArray, v2: FloatArray
) -> FloatArray:
    """Distance driven at times ``t``: constant acceleration within each 1 m cell.

    v^2 is linear in s within a cell, i.e. the acceleration is constant there,
    so s is exactly quadratic in time and speed is continuous (a linear
    interpolation of s would make speed jump at every node and, near a stop,
    by a whole metre per cell-time). Before leaving node 0 and while waiting
    at a stop the distance stays put.
    """
    cell = np.clip(np.searchsorted(leave, t, side="right") - 1, 0, cell_dt.size - 1)
    tau = np.clip(t - leave[cell], 0.0, cell_dt[cell])
    v = np.sqrt(v2)
    accel = (v2[cell + 1] - v2[cell]) / (2.0 * _DS)
    return np.asarray(cell * _DS + v[cell] * tau + 0.5 * accel * tau * tau, dtype=np.float64)


@dataclass
class _Truth:
    """True motion at the output samples (plus what the sensors need)."""

    t: FloatArray  # s from the start
    east: FloatArray
    north: FloatArray
    speed: FloatArray  # m/s
    accel: FloatArray  # m/s^2 along the path
    heading: FloatArray  # degrees clockwise from north, unwrapped
    kappa: FloatArray  # 1/m, positive clockwise
    alt: FloatArray
    grade: FloatArray
    hold: NDArray[np.bool_]  # receiver in static hold


def _motion(
    route: _Route, n_out: int, rate_hz: float, heading0: float, p: SimulatorParams
) -> _Truth:
    """Turn the route into smoothed, jerk-limited motion sampled at ``rate_hz``."""
    cap2 = _speed_cap_squared(route, p)
    # Cars pull (and drivers brake) less hard at speed: scale the limits by the
    # speed a first pass reaches at each node, then plan again.
    first = np.sqrt(_speed_profile(cap2, route.accel, route.decel))
    fade = np.maximum(p.accel_fade_floor, 1.0 - first / p.accel_fade_speed)
    v2 = _speed_profile(cap2, route.accel * fade, route.decel * fade)
    v = np.sqrt(v2)
    n_nodes = v.size
    s_nodes = np.arange(n_nodes) * _DS
    cell_dt = 2.0 * _DS / np.maximum(v[:-1] + v[1:], 1e-12)
    wait = np.zeros(n_nodes)
    np.add.at(wait, route.stop_node, route.stop_wait)
    arrive = np.concatenate([[0.0], np.cumsum(cell_dt)]) + np.concatenate(
        [[0.0], np.cumsum(wait)[:-1]]
    )
    leave = arrive + wait

    sub = max(1, math.ceil(1.0 / (rate_hz * _FINE_DT)))
    h = 1.0 / (rate_hz * sub)
    half = max(1, round(p.smoothing_time / h / 2))
    n_fine = (n_out - 1) * sub + 1
    # Pad by the box half-width plus the two samples the two derivatives look at,
    # so no output sample sees the box filter's edge padding.
    pad = half + 2
    t_fine = (np.arange(n_fine + 2 * pad, dtype=np.float64) - pad) * h
    s_raw = _distance_at(t_fine, leave, cell_dt, v2)
    s_smooth = _box_mean(s_raw, 2 * half + 1)
    v_fine = np.gradient(s_smooth, h)
    a_fine = np.gradient(v_fine, h)
    out = slice(pad, pad + n_fine, sub)
    s_out = s_smooth[out]

    psi_nodes = math.radians(heading0) + np.concatenate(
        [[0.0], np.cumsum(0.5 * (route.kappa[:-1] + route.kappa[1:]) * _DS)]
    )
    psi_mid = 0.5 * (psi_nodes[:-1] + psi_nodes[1:])
    east_nodes = np.concatenate([[0.0], np.cumsum(np.sin(psi_mid) * _DS)])
    north_nodes = np.concatenate([[0.0], np.cumsum(np.cos(psi_mid) * _DS)])
    alt_nodes = p.origin_alt + np.concatenate([[0.0], np.cumsum(route.grade[:-1] * _DS)])

    # Static hold: every run of samples slower than the receiver's threshold that
    # reaches into a held stop (between arriving and leaving), so the fix pins while
    # the car still rolls in and lets go once it rolls out faster than that.
    t_out = t_fine[out]
    stop_idx = np.searchsorted(leave[route.stop_node], t_out, side="left")
    stop_idx = np.minimum(stop_idx, route.stop_node.size - 1)
    at_stop = (t_out >= arrive[route.stop_node][stop_idx]) & (
        t_out <= leave[route.stop_node][stop_idx]
    )
    slow = v_fine[out] < route.hold_speed
    run = np.cumsum(np.r_[True, slow[1:] != slow[:-1]])
    held_runs = np.unique(run[at_stop & route.stop_hold[stop_idx] & slow])
    hold = slow & np.isin(run, held_runs)

    return _Truth(
        t=t_out,
        east=np.interp(s_out, s_nodes, east_nodes),
        north=np.interp(s_out, s_nodes, north_nodes),
        speed=v_fine[out],
        accel=a_fine[out],
        heading=np.degrees(np.interp(s_out, s_nodes, psi_nodes)),
        kappa=np.interp(s_out, s_nodes, route.kappa),
        alt=np.interp(s_out, s_nodes, alt_nodes),
        grade=np.interp(s_out, s_nodes, route.grade),
        hold=hold,
    )


# ---------------------------------------------------------------------------
# Sensors
# ---------------------------------------------------------------------------


def _gauss_markov(
    rng: np.random.Generator, n: int, sigma: float, tau: float, dt: float
) -> FloatArray:
    """Stationary first-order Gauss-Markov sequence: x_k = phi x_{k-1} + w_k, std ``sigma``."""
    phi = math.exp(-dt / tau)
    innovations = rng.normal(0.0, sigma * math.sqrt(1.0 - phi * phi), n)
    innovations[0] = rng.normal(0.0, sigma)
    return _ar1(innovations, phi)


def _ar1(innovations: FloatArray, phi: float) -> FloatArray:
    """x_0 = w_0, x_k = phi x_{k-1} + w_k, vectorised in blocks.

    Within a block starting at x_s: x_{s+k} = phi^k (x_s + sum_{j=1..k} phi^-j w_{s+j}),
    a cumulative sum. Blocks keep phi^-k under e^10 so the sum stays accurate.
    ``phi`` must be in [0, 1].
    """
    n = innovations.size
    out = np.empty(n)
    if n == 0:
        return out
    if phi < 0.3:
        # Memory shorter than ~33 steps (phi^33 < 1e-17): sum the truncated series directly.
        out[:] = innovations
        weight = 1.0
        for lag in range(1, n):
            weight *= phi
            if weight < 1e-17:
                break
            out[lag:] += weight * innovations[:-lag]
        return out
    block = min(n, int(10.0 / -math.log(phi))) if phi < 1.0 else n
    out[0] = innovations[0]
    start = 0
    while start < n - 1:
        stop = min(n, start + 1 + block)
        k = np.arange(1, stop - start, dtype=np.float64)
        out[start + 1 : stop] = phi**k * (
            out[start] + np.cumsum(phi**-k * innovations[start + 1 : stop])
        )
        start = stop - 1
    return out


def _ar1_reference(innovations: FloatArray, phi: float) -> FloatArray:
    """The recursion of :func:`_ar1` as a plain loop, for tests."""
    out = np.empty(innovations.size)
    for k in range(innovations.size):
        out[k] = innovations[k] + (phi * out[k - 1] if k else 0.0)
    return out


def _epoch_noise(rng: np.random.Generator, n: int, dof: float) -> FloatArray:
    """Student-t samples (``dof`` = 0 means Gaussian): mostly small, now and then a multipath-sized outlier."""
    if dof == 0:
        return rng.standard_normal(n)
    return rng.standard_t(dof, n)


def _freeze(values: FloatArray, hold: NDArray[np.bool_]) -> FloatArray:
    """Repeat the last value before each held run through the run (what a receiver reports)."""
    idx = np.where(hold, 0, np.arange(values.size))
    return values[np.maximum.accumulate(idx)]


def _measure(
    rng: np.random.Generator, truth: _Truth, rate_hz: float, p: SimulatorParams
) -> dict[str, FloatArray]:
    n = truth.t.size
    dt = 1.0 / rate_hz
    hdop = np.maximum(
        p.hdop_min,
        p.hdop_median
        * np.exp(_gauss_markov(rng, n, p.hdop_log_sigma, p.hdop_correlation_time, dt)),
    )
    hdop = np.round(hdop, 2)
    white_scale = p.gnss_white_sigma * hdop / p.hdop_median
    east = (
        truth.east
        + _gauss_markov(rng, n, p.gnss_correlated_sigma, p.gnss_correlation_time, dt)
        + white_scale * _epoch_noise(rng, n, p.gnss_white_dof)
    )
    north = (
        truth.north
        + _gauss_markov(rng, n, p.gnss_correlated_sigma, p.gnss_correlation_time, dt)
        + white_scale * _epoch_noise(rng, n, p.gnss_white_dof)
    )
    alt = truth.alt + _gauss_markov(rng, n, p.vertical_sigma, p.gnss_correlation_time, dt)
    psi = np.radians(truth.heading)
    v_east = truth.speed * np.sin(psi) + rng.normal(0.0, p.velocity_sigma, n)
    v_north = truth.speed * np.cos(psi) + rng.normal(0.0, p.velocity_sigma, n)
    speed = np.hypot(v_east, v_north)
    heading = np.mod(np.degrees(np.arctan2(v_east, v_north)), 360.0)
    accel_bias = rng.normal(0.0, p.accel_bias_sigma)
    gyro_bias = rng.normal(0.0, p.gyro_bias_sigma)
    accel_x = (
        truth.accel
        + _GRAVITY * np.sin(np.arctan(truth.grade))
        + accel_bias
        + rng.normal(0.0, p.accel_noise_sigma, n)
    )
    # Yaw rate: counterclockwise positive (ISO 8855, and the real logger), so minus v*kappa.
    yaw_rate = (
        -np.degrees(truth.speed * truth.kappa) + gyro_bias + rng.normal(0.0, p.gyro_noise_sigma, n)
    )

    hold = truth.hold
    return {
        "east": _freeze(east, hold),
        "north": _freeze(north, hold),
        "alt": _freeze(alt, hold),
        "speed": np.where(hold, 0.0, speed),
        "heading": _freeze(heading, hold),
        "hdop": hdop,
        "accel_x": accel_x,
        "yaw_rate": yaw_rate,
    }


# ---------------------------------------------------------------------------
# Public API
# ---------------------------------------------------------------------------


def _check_args(minutes: float, rate_hz: float, origin: tuple[float, float]) -> None:
    if not (isinstance(minutes, int | float) and math.isfinite(minutes) and 0 < minutes <= 24 * 60):
        raise ConfigError(f"minutes must be in (0, 1440], got {minutes!r}")
    if not (isinstance(rate_hz, int | float) and math.isfinite(rate_hz) and 0.1 <= rate_hz <= 100):
        raise ConfigError(f"rate_hz must be in [0.1, 100], got {rate_hz!r}")
    lat, lon = origin
    if not (-80.0 <= lat <= 80.0 and -180.0 <= lon <= 180.0):
        raise ConfigError(
            f"origin must be (lat, lon) with |lat| <= 80 and |lon| <= 180, got {origin!r}"
        )


def _simulate_truth(
    minutes: float, rate_hz: float, seed: int, track: int, p: SimulatorParams
) -> tuple[np.random.Generator, _Truth]:
    """The true motion of a track, and the random stream positioned for its sensors."""
    rng = np.random.default_rng(np.random.SeedSequence([seed, track]))
    n_out = max(1, round(minutes * 60.0 * rate_hz))
    duration = (n_out - 1) / rate_hz
    heading0 = rng.uniform(0.0, 360.0)
    route = _plan_route(rng, duration, p)
    return rng, _motion(route, n_out, rate_hz, heading0, p)


def _simulate_track(
    minutes: float,
    rate_hz: float,
    seed: int,
    track: int,
    origin: tuple[float, float],
    p: SimulatorParams,
    imu: bool,
) -> pd.DataFrame:
    rng, truth = _simulate_truth(minutes, rate_hz, seed, track, p)
    n_out = truth.t.size
    m = _measure(rng, truth, rate_hz, p)
    lat, lon = LocalFrame(*origin).to_geodetic(m["east"], m["north"])
    columns: dict[str, object] = {
        "track": [str(track)] * n_out,
        "t": EPOCH + np.arange(n_out) / rate_hz,
        "lat": np.round(lat, 7),
        "lon": np.round(lon, 7),
        "speed": np.round(m["speed"], 3),
        "heading": np.round(m["heading"], 2) % 360.0,
        "alt": np.round(m["alt"], 1),
        "hdop": m["hdop"],
    }
    if imu:
        columns["accel_x"] = np.round(m["accel_x"], 3)
        columns["yaw_rate"] = np.round(m["yaw_rate"], 3)
    return pd.DataFrame(columns)


def simulate_drive(
    minutes: float,
    rate_hz: float = 1.0,
    seed: int = 0,
    *,
    origin: tuple[float, float] = DEFAULT_ORIGIN,
    params: SimulatorParams | None = None,
    imu: bool = True,
    track: int = 0,
) -> pd.DataFrame:
    """Simulate one car drive of ``minutes`` sampled at ``rate_hz``, starting at ``origin``.

    Returns canonical fixes: ``track`` (``str(track)``), ``t`` (unix seconds
    from :data:`EPOCH`), ``lat``, ``lon`` (degrees, 7 decimals), ``speed``
    (m/s), ``heading`` (degrees [0, 360)), ``alt`` (m), ``hdop``, and with
    ``imu`` ``accel_x`` (longitudinal, m/s^2, includes the road grade's
    gravity component and a bias) and ``yaw_rate`` (deg/s, counterclockwise
    positive). The drive is a pure function of the arguments: ``seed`` and
    ``track`` select the random stream, so the same call gives the same bytes.
    """
    _check_args(minutes, rate_hz, origin)
    return _simulate_track(minutes, rate_hz, seed, track, origin, params or SimulatorParams(), imu)


def _fleet_origin(
    origin: tuple[float, float], spread_km: float, seed: int, track: int
) -> tuple[float, float]:
    """Start point of fleet track ``track``: uniform in a square of side 2 x spread_km around ``origin``."""
    rng = np.random.default_rng(np.random.SeedSequence([seed, track, 1]))
    d_north, d_east = rng.uniform(-spread_km * 1000.0, spread_km * 1000.0, 2)
    frame = LocalFrame(*origin)
    lat, lon = frame.to_geodetic(d_east, d_north)
    return float(np.round(lat, 7)), float(np.round(lon, 7))


def simulate_fleet(
    n_tracks: int,
    minutes: float,
    rate_hz: float = 1.0,
    seed: int = 0,
    *,
    origin: tuple[float, float] = DEFAULT_ORIGIN,
    spread_km: float = 20.0,
    params: SimulatorParams | None = None,
    imu: bool = True,
    on_track: Callable[[int], None] | None = None,
) -> pd.DataFrame:
    """Simulate ``n_tracks`` drives (track ids ``"0"``..), stacked in one frame.

    Track ``i`` starts at a point drawn from ``(seed, i)`` within
    ``spread_km`` of ``origin`` and has its own road mix and driver; it is
    exactly ``simulate_drive(minutes, rate_hz, seed, origin=<that point>,
    track=i)``, so any track can be regenerated alone. ``on_track(i)`` is
    called after each track (progress bars).
    """
    if not (isinstance(n_tracks, int) and n_tracks >= 1):
        raise ConfigError(f"n_tracks must be an integer >= 1, got {n_tracks!r}")
    if not (math.isfinite(spread_km) and spread_km >= 0):
        raise ConfigError(f"spread_km must be finite and >= 0, got {spread_km!r}")
    _check_args(minutes, rate_hz, origin)
    p = params or SimulatorParams()
    frames = []
    for i in range(n_tracks):
        start = _fleet_origin(origin, spread_km, seed, i)
        frames.append(_simulate_track(minutes, rate_hz, seed, i, start, p, imu))
        if on_track is not None:
            on_track(i)
    return pd.concat(frames, ignore_index=True)

"""The peers: what a user would pick instead of gradgps, each through its own documented API.

Not the paper's baselines (those are :mod:`.kalman`, :mod:`.cnn`, ...) but the
tools a person cleaning vehicle GPS tracks reaches for today, used the way
their documentation shows, behind the batch interface of every detector here
(``detect(fixes) -> one result row per input row``):

``movingpandas-outlier``
    ``movingpandas.OutlierCleaner(collection).clean(v_max=..., units=("km", "h"))``
    (or ``alpha`` × IQR when ``v_max`` is ``None``); a fix it removes is flagged.
``movingpandas-kalman``
    ``movingpandas.KalmanSmootherCV(collection).smooth(process_noise_std, measurement_noise_std)``;
    a fix more than ``threshold`` metres from the smoothed track is flagged.
``skmob-filter``
    scikit-mobility ``preprocessing.filtering.filter(tdf, max_speed_kmh=...)``; a fix
    it removes is flagged. It cannot share our environment (see :mod:`.skmob_peer`).
``kalman-chi2``, ``kalman-chi2-vel``
    ``filterpy.kalman.KalmanFilter``, constant velocity in east/north metres
    (``Q_discrete_white_noise``), with a chi-square gate on the innovation: a
    fix whose normalised innovation squared exceeds the ``gate`` quantile is
    flagged and not used to update. ``-vel`` also measures the reported speed
    and heading as a velocity (positions only where they are missing).
``hampel``
    Hampel filter: rolling median and MAD (``pandas.Series.rolling``, centred
    window of ``2·window+1`` fixes) on east and north metres; flagged when
    ``|x - median| > threshold · 1.4826 · MAD`` on either axis.
``river-gauss``
    ``river.anomaly.GaussianScorer`` on one scalar per fix (the implied
    acceleration, or with reported speed the gap between reported and
    implied speed), ``score_one`` then ``learn_one``, per track.
``river-hst``
    ``river.preprocessing.MinMaxScaler() | river.anomaly.HalfSpaceTrees(...)``
    on (step, implied speed, heading change [, reported speed, speed gap,
    heading gap]), ``score_one`` then ``learn_one``, per track.
``pyod-iforest``
    ``pyod.models.iforest.IForest(contamination=...)`` fitted on the features
    of the fixes it is given (all tracks) and asked for ``labels_``.

Two input variants decide what a peer may read: ``positions`` (t, lat, lon)
and ``+speed+heading`` (the reported speed and heading too, where the fixes
carry them). A peer that does not use speed or heading gives the same answer
in both. Each peer's settings come per variant (``settings[variant]``); the
benchmark tunes them on a validation split (:mod:`gradgps._eval.peers`).

Fixes are taken per track in time order; unusable fixes (time or position
missing or out of range) are flagged with their reason and never enter a
peer's state, as for the other baselines (:mod:`gradgps._result`). The
filters that keep state (``kalman-chi2*``, ``river-*``) have a streaming
object (``update(t, lat, lon, speed, heading) -> PointResult``, checking
each fix as every baseline's stream does, a fix before the previous usable
one included); their batch ``detect`` is that object fed one fix at a
time, so both modes give the same answer.
"""

from __future__ import annotations

import importlib
import json
import math
import warnings
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from pathlib import Path
from types import ModuleType
from typing import Any

import numpy as np
import pandas as pd

from .._exceptions import ConfigError
from .._result import PointResult, result_frame
from .._tracks.geo import LocalFrame
from .base import FixStream, Reading, segments

__all__ = [
    "DEFAULT_SETTINGS",
    "PEER_NAMES",
    "SKMOB_LAST_SECONDS",
    "STREAMING_PEERS",
    "TUNED_FILE",
    "VARIANTS",
    "PeerDetector",
    "PeerTrack",
    "peer_raw",
    "peer_stream",
    "peer_tracks",
    "require",
    "threshold_of",
    "tuned_settings",
    "variant_of",
]

PEER_NAMES = (
    "movingpandas-outlier",
    "movingpandas-kalman",
    "skmob-filter",
    "kalman-chi2",
    "kalman-chi2-vel",
    "hampel",
    "river-gauss",
    "river-hst",
    "pyod-iforest",
)
VARIANTS = ("positions", "+speed+heading")
#: Peers with a per-fix streaming object (:func:`peer_stream`).
STREAMING_PEERS = ("kalman-chi2", "kalman-chi2-vel", "river-gauss", "river-hst")

#: Each peer's settings before tuning: the library's documented defaults where it has
#: them, a threshold otherwise. ``threshold`` applies to the raw score of :func:`peer_raw`.
DEFAULT_SETTINGS: dict[str, dict[str, Any]] = {
    "movingpandas-outlier": {"v_max": None, "alpha": 3.0, "threshold": 0.5},
    "movingpandas-kalman": {
        "process_noise_std": 0.5,
        "measurement_noise_std": 1.0,
        "threshold": 10.0,
    },
    "skmob-filter": {"max_speed_kmh": 500.0, "threshold": 0.5},
    "kalman-chi2": {"q": 1.0, "r": 9.0, "gate": 0.999},
    "kalman-chi2-vel": {"q": 1.0, "r": 9.0, "r_vel": 1.0, "gate": 0.999},
    "hampel": {"window": 5, "threshold": 3.0},
    "river-gauss": {
        "feature": "accel",
        "window_size": None,
        "grace_period": 100,
        "threshold": 0.99,
    },
    "river-hst": {"window_size": 250, "n_trees": 10, "height": 8, "threshold": 0.9},
    "pyod-iforest": {"contamination": 0.1, "n_estimators": 100},
}

#: Fixes further apart than this (s) start a new segment for the stateful filters.
MAX_GAP_S = 5.0
#: Which Python module each peer needs (all from the ``peers`` extra).
_MODULES = {
    "movingpandas-outlier": "movingpandas",
    "movingpandas-kalman": "movingpandas",
    "kalman-chi2": "filterpy.kalman",
    "kalman-chi2-vel": "filterpy.kalman",
    "river-gauss": "river.anomaly",
    "river-hst": "river.anomaly",
    "pyod-iforest": "pyod.models.iforest",
}


#: Settings tuned on each data set's validation split, ``{dataset: {variant: {peer: settings}}}``,
#: written by ``python benchmarks/peers.py --tune`` (see :mod:`gradgps._eval.peers`).
TUNED_FILE = Path(__file__).with_name("peers_tuned.json")


def tuned_settings(name: str, dataset: str | None) -> dict[str, dict[str, Any]]:
    """Peer ``name``'s tuned settings per variant on ``dataset`` (empty: the defaults apply)."""
    if dataset is None or not TUNED_FILE.is_file():
        return {}
    tuned = json.loads(TUNED_FILE.read_text()).get(dataset, {})
    out = {}
    for variant, peers in tuned.items():
        if name in peers:
            out[variant] = {k: v for k, v in peers[name].items() if k != "validation_f1"}
    return out


def require(module: str, what: str) -> ModuleType:
    """Import ``module`` or fail with one line naming the ``peers`` extra."""
    try:
        return importlib.import_module(module)
    except ImportError as exc:
        raise ConfigError(
            f"{what} needs the optional extra 'peers' ({module} is not installed): "
            "pip install 'gradgps[peers]'"
        ) from exc


def variant_of(fixes: pd.DataFrame) -> str:
    """``+speed+heading`` when the fixes carry a reported speed and heading, else ``positions``."""
    has = all(
        c in fixes.columns and bool(np.isfinite(fixes[c].to_numpy(dtype=np.float64)).any())
        for c in ("speed", "heading")
    )
    return "+speed+heading" if has else "positions"


def _check_name(name: str) -> None:
    if name not in PEER_NAMES:
        raise ConfigError(f"unknown peer {name!r}; known peers: {', '.join(PEER_NAMES)}")


# ----------------------------------------------------------------------------
# Tracks and per-fix features
# ----------------------------------------------------------------------------


@dataclass(frozen=True)
class PeerTrack:
    """One track's usable fixes in time order (``rows`` index the input frame)."""

    rows: np.ndarray
    t: np.ndarray
    lat: np.ndarray
    lon: np.ndarray
    east: np.ndarray
    north: np.ndarray
    speed: np.ndarray | None
    heading: np.ndarray | None
    frame: LocalFrame


def peer_tracks(fixes: pd.DataFrame, variant: str) -> tuple[list[PeerTrack], np.ndarray]:
    segs, reason = segments(fixes, "position", max_gap_s=math.inf)
    lat = fixes["lat"].to_numpy(dtype=np.float64)
    lon = fixes["lon"].to_numpy(dtype=np.float64)
    use = variant == "+speed+heading"
    speed = fixes["speed"].to_numpy(dtype=np.float64) if use and "speed" in fixes else None
    heading = fixes["heading"].to_numpy(dtype=np.float64) if use and "heading" in fixes else None
    out = [
        PeerTrack(
            s.rows,
            s.t,
            lat[s.rows],
            lon[s.rows],
            s.values[:, 0],
            s.values[:, 1],
            None if speed is None else speed[s.rows],
            None if heading is None else heading[s.rows],
            s.frame,
        )
        for s in segs
    ]
    return out, reason


def _wrap_deg(d: float) -> float:
    return abs((d + 180.0) % 360.0 - 180.0)


class _Features:
    """Per-fix features from positions (and reported speed/heading), one fix at a time.

    ``step`` m, ``speed`` m/s and ``accel`` m/s² (magnitude of the change of
    the implied velocity vector), ``turn`` degrees of course change; with a
    reported speed/heading also ``reported_speed``, ``speed_gap`` (m/s,
    reported minus implied, absolute) and ``heading_gap`` (degrees between
    reported heading and the implied course). Undefined values are 0.
    """

    def __init__(self, use_reported: bool) -> None:
        self.use_reported = use_reported
        self._last: tuple[float, float, float] | None = None
        self._vel: tuple[float, float] | None = None
        self._course: float | None = None

    def update(
        self, t: float, east: float, north: float, speed: float, heading: float
    ) -> dict[str, float]:
        step = sp = acc = turn = 0.0
        if self._last is not None:
            t0, e0, n0 = self._last
            de, dn, dt = east - e0, north - n0, t - t0
            step = math.hypot(de, dn)
            if dt > 0:
                ve, vn = de / dt, dn / dt
                sp = math.hypot(ve, vn)
                if self._vel is not None:
                    acc = math.hypot(ve - self._vel[0], vn - self._vel[1]) / dt
                self._vel = (ve, vn)
                if step > 0.5:
                    course = math.degrees(math.atan2(de, dn)) % 360.0
                    if self._course is not None:
                        turn = _wrap_deg(course - self._course)
                    self._course = course
        self._last = (t, east, north)
        out = {"step": step, "speed": sp, "accel": acc, "turn": turn}
        if self.use_reported:
            rs = speed if math.isfinite(speed) else 0.0
            out["reported_speed"] = rs
            out["speed_gap"] = abs(rs - sp) if math.isfinite(speed) else 0.0
            out["heading_gap"] = (
                _wrap_deg(heading - self._course)
                if math.isfinite(heading) and self._course is not None
                else 0.0
            )
        return out


def _value(values: np.ndarray | None, i: int) -> float:
    return math.nan if values is None else float(values[i])


# ----------------------------------------------------------------------------
# Streaming peers: one object per track
# ----------------------------------------------------------------------------


class _Stream(FixStream):
    """Base of the streaming peers: local frame, raw score per fix; ``update`` checks each
    fix as every baseline's stream does (:class:`gradgps._baselines.base.FixStream`)."""

    def __init__(self, settings: Mapping[str, Any], use_reported: bool) -> None:
        self.settings = dict(settings)
        self.use_reported = use_reported
        self._frame: LocalFrame | None = None

    def raw(self, t: float, east: float, north: float, speed: float, heading: float) -> float:
        raise NotImplementedError

    def clean(self) -> tuple[float, float] | None:
        """East/north to use instead of the last fix, or None to keep it."""
        return None

    def threshold(self) -> float:
        return float(self.settings["threshold"])

    def step(
        self, t: float, lat: float, lon: float, speed: float, heading: float
    ) -> tuple[float, float, float]:
        """Raw score, ``lat_clean``, ``lon_clean`` of one usable fix."""
        if self._frame is None:
            self._frame = LocalFrame(lat, lon)
        e, n = self._frame.to_local(np.array([lat]), np.array([lon]))
        raw = self.raw(t, float(e[0]), float(n[0]), speed, heading)
        better = self.clean()
        if better is None:
            return raw, lat, lon
        la, lo = self._frame.to_geodetic(np.array([better[0]]), np.array([better[1]]))
        return raw, float(la[0]), float(lo[0])

    def _update_valid(self, fix: Reading) -> PointResult:
        """Score one usable fix of this stream's track (its ``channels`` are ignored)."""
        raw, lat_c, lon_c = self.step(fix.t, fix.lat, fix.lon, fix.speed, fix.heading)
        self._last_t = fix.t
        thr = self.threshold()
        return PointResult(int(raw > thr), _score(raw, thr), None, None, lat_c, lon_c, 0)


def _score(raw: float, threshold: float) -> float:
    """Raw score to [0, 1], 0.5 exactly at the threshold."""
    if not math.isfinite(raw):
        return 1.0 if raw > 0 else 0.0
    if threshold <= 0:
        return 1.0 if raw > threshold else 0.0
    return max(raw, 0.0) / (max(raw, 0.0) + threshold)


class KalmanChi2Stream(_Stream):
    """filterpy ``KalmanFilter``, constant velocity in east/north, chi-square gate.

    Raw score: the chi-square CDF of the innovation's NIS (2 degrees of freedom
    for a position, 4 with a velocity), compared with ``gate``.
    """

    def __init__(self, settings: Mapping[str, Any], use_reported: bool) -> None:
        super().__init__(settings, use_reported)
        kalman = require("filterpy.kalman", "detector 'kalman-chi2'")
        common = require("filterpy.common", "detector 'kalman-chi2'")
        self._kf_class = kalman.KalmanFilter
        self._q_noise = common.Q_discrete_white_noise
        self._kf: Any = None
        self._prev_t = math.nan  # time of the last fix scored (NaN: none yet)
        self._x_clean: tuple[float, float] | None = None
        r = float(self.settings["r"])
        self._h_pos = np.array([[1.0, 0, 0, 0], [0, 1.0, 0, 0]])
        self._r_pos = np.eye(2) * r
        self._h_vel = np.eye(4)
        r_vel = float(self.settings.get("r_vel", 1.0))
        self._r_vel = np.diag([r, r, r_vel, r_vel])

    def threshold(self) -> float:
        return float(self.settings["gate"])

    def _start(self, z: np.ndarray, has_vel: bool) -> None:
        kf = self._kf_class(dim_x=4, dim_z=2)
        kf.x = np.array([z[0], z[1], z[2] if has_vel else 0.0, z[3] if has_vel else 0.0])
        r = float(self.settings["r"])
        kf.P = np.diag([r, r, 1.0 if has_vel else 1e4, 1.0 if has_vel else 1e4])
        kf.H = self._h_pos
        kf.R = self._r_pos
        self._kf = kf

    def raw(self, t: float, east: float, north: float, speed: float, heading: float) -> float:
        has_vel = self.use_reported and math.isfinite(speed) and math.isfinite(heading)
        if has_vel:
            h = math.radians(heading)
            z = np.array([east, north, speed * math.sin(h), speed * math.cos(h)])
            big_h, big_r = self._h_vel, self._r_vel
        else:
            z = np.array([east, north])
            big_h, big_r = self._h_pos, self._r_pos
        dt = t - self._prev_t
        self._prev_t = t
        if self._kf is None or not (dt <= MAX_GAP_S):
            self._start(z, has_vel)
            self._x_clean = None
            return 0.0
        kf = self._kf
        dt = max(dt, 0.0)
        kf.F = np.array([[1, 0, dt, 0], [0, 1, 0, dt], [0, 0, 1, 0], [0, 0, 0, 1.0]])
        kf.Q = self._q_noise(
            dim=2, dt=max(dt, 1e-3), var=float(self.settings["q"]), block_size=2, order_by_dim=False
        )
        kf.predict()
        y = z - big_h @ kf.x
        s = big_h @ kf.P @ big_h.T + big_r
        nis = float(y @ np.linalg.solve(s, y))
        half = nis / 2.0
        cdf = 1.0 - math.exp(-half) if z.size == 2 else 1.0 - math.exp(-half) * (1.0 + half)
        if cdf > self.threshold():
            self._x_clean = (float(kf.x[0]), float(kf.x[1]))
        else:
            kf.update(z, R=big_r, H=big_h)
            self._x_clean = None
        return cdf

    def clean(self) -> tuple[float, float] | None:
        return self._x_clean


class RiverGaussStream(_Stream):
    """``river.anomaly.GaussianScorer`` on one feature per fix: ``score_one`` then ``learn_one``."""

    def __init__(self, settings: Mapping[str, Any], use_reported: bool) -> None:
        super().__init__(settings, use_reported)
        anomaly = require("river.anomaly", "detector 'river-gauss'")
        feature = str(self.settings["feature"])
        if feature != "accel" and not use_reported:
            feature = "accel"  # a reported-speed feature needs the reported speed
        self._feature = feature
        self._scorer = anomaly.GaussianScorer(
            window_size=self.settings.get("window_size"),
            grace_period=int(self.settings.get("grace_period", 100)),
        )
        self._features = _Features(use_reported)

    def raw(self, t: float, east: float, north: float, speed: float, heading: float) -> float:
        y = self._features.update(t, east, north, speed, heading)[self._feature]
        score = float(self._scorer.score_one(None, y))
        self._scorer.learn_one(None, y)
        return score


class RiverHstStream(_Stream):
    """``MinMaxScaler() | HalfSpaceTrees(...)`` on the per-fix features, ``score_one`` then ``learn_one``."""

    def __init__(self, settings: Mapping[str, Any], use_reported: bool) -> None:
        super().__init__(settings, use_reported)
        anomaly = require("river.anomaly", "detector 'river-hst'")
        preprocessing = require("river.preprocessing", "detector 'river-hst'")
        self._model = preprocessing.MinMaxScaler() | anomaly.HalfSpaceTrees(
            n_trees=int(self.settings["n_trees"]),
            height=int(self.settings["height"]),
            window_size=int(self.settings["window_size"]),
            seed=0,
        )
        self._features = _Features(use_reported)

    def raw(self, t: float, east: float, north: float, speed: float, heading: float) -> float:
        x = self._features.update(t, east, north, speed, heading)
        x.pop("accel")
        score = float(self._model.score_one(x))
        self._model.learn_one(x)
        return score


_STREAMS: dict[str, Callable[[Mapping[str, Any], bool], _Stream]] = {
    "kalman-chi2": lambda s, r: KalmanChi2Stream(s, False),
    "kalman-chi2-vel": KalmanChi2Stream,
    "river-gauss": RiverGaussStream,
    "river-hst": RiverHstStream,
}


def peer_stream(name: str, settings: Mapping[str, Any], variant: str) -> _Stream:
    """A fresh streaming object of a streaming peer for one track."""
    _check_name(name)
    if name not in _STREAMS:
        raise ConfigError(
            f"peer {name!r} has no streaming form; streaming peers: {', '.join(STREAMING_PEERS)}"
        )
    return _STREAMS[name](settings, variant == "+speed+heading")


# ----------------------------------------------------------------------------
# Batch peers
# ----------------------------------------------------------------------------

_Raw = tuple[np.ndarray, np.ndarray, np.ndarray]  # raw score, lat_clean, lon_clean (per row)


def _from_streams(
    name: str, tracks: list[PeerTrack], n: int, settings: Mapping[str, Any], variant: str
) -> _Raw:
    raw = np.zeros(n)
    lat_c = np.full(n, math.nan)
    lon_c = np.full(n, math.nan)
    for tr in tracks:
        stream = peer_stream(name, settings, variant)
        for i, row in enumerate(tr.rows):
            raw[row], lat_c[row], lon_c[row] = stream.step(
                float(tr.t[i]),
                float(tr.lat[i]),
                float(tr.lon[i]),
                _value(tr.speed, i),
                _value(tr.heading, i),
            )
    return raw, lat_c, lon_c


def _hampel(tracks: list[PeerTrack], n: int, settings: Mapping[str, Any]) -> _Raw:
    w = int(settings["window"])
    raw = np.zeros(n)
    lat_c = np.full(n, math.nan)
    lon_c = np.full(n, math.nan)
    for tr in tracks:
        devs, meds = [], []
        for x in (tr.east, tr.north):
            s = pd.Series(x)
            med = s.rolling(2 * w + 1, center=True, min_periods=1).median()
            mad = (s - med).abs().rolling(2 * w + 1, center=True, min_periods=1).median()
            scale = 1.4826 * mad.to_numpy()
            dev = np.abs(x - med.to_numpy())
            devs.append(np.where(scale > 0, dev / np.where(scale > 0, scale, 1.0), 0.0))
            meds.append(med.to_numpy())
        r = np.maximum(devs[0], devs[1])
        raw[tr.rows] = r
        flag = r > float(settings["threshold"])
        e = np.where(flag, meds[0], tr.east)
        no = np.where(flag, meds[1], tr.north)
        la, lo = tr.frame.to_geodetic(e, no)
        lat_c[tr.rows], lon_c[tr.rows] = la, lo
    return raw, lat_c, lon_c


def _collection(tracks: list[PeerTrack]) -> Any:
    """The tracks as a movingpandas ``TrajectoryCollection`` (WGS84 points, a ``row`` column)."""
    mpd = require("movingpandas", "the movingpandas peers")
    gpd = require("geopandas", "the movingpandas peers")
    parts = []
    for k, tr in enumerate(tracks):
        parts.append(
            pd.DataFrame(
                {
                    "traj": k,
                    "time": pd.to_datetime(tr.t, unit="s"),
                    "row": tr.rows,
                    "lat": tr.lat,
                    "lon": tr.lon,
                }
            )
        )
    df = pd.concat(parts, ignore_index=True)
    gdf = gpd.GeoDataFrame(df, geometry=gpd.points_from_xy(df["lon"], df["lat"]), crs="EPSG:4326")
    return mpd.TrajectoryCollection(gdf, traj_id_col="traj", t="time")


def _kept_rows(collection: Any) -> np.ndarray:
    rows = [t.df["row"].to_numpy() for t in collection.trajectories]
    return np.concatenate(rows).astype(np.int64) if rows else np.zeros(0, np.int64)


def _mpd_outlier(tracks: list[PeerTrack], n: int, settings: Mapping[str, Any]) -> _Raw:
    mpd = require("movingpandas", "detector 'movingpandas-outlier'")
    raw = np.zeros(n)
    usable = np.concatenate([tr.rows for tr in tracks]) if tracks else np.zeros(0, np.int64)
    if usable.size:
        with warnings.catch_warnings():
            # the library's own deprecation/runtime warnings, not ours
            warnings.simplefilter("ignore")
            tc = _collection(tracks)
            v_max = settings.get("v_max")
            cleaner = mpd.OutlierCleaner(tc)
            if v_max is None:
                cleaned = cleaner.clean(alpha=float(settings["alpha"]))
            else:
                cleaned = cleaner.clean(v_max=float(v_max), units=("km", "h"))
        raw[usable] = 1.0
        raw[_kept_rows(cleaned)] = 0.0
    return _dropped(tracks, raw, n)


def _dropped(tracks: list[PeerTrack], raw: np.ndarray, n: int) -> _Raw:
    """Removers repair nothing: a removed fix has no position to use instead."""
    lat_c = np.full(n, math.nan)
    lon_c = np.full(n, math.nan)
    for tr in tracks:
        keep = raw[tr.rows] <= 0.5
        lat_c[tr.rows] = np.where(keep, tr.lat, math.nan)
        lon_c[tr.rows] = np.where(keep, tr.lon, math.nan)
    return raw, lat_c, lon_c


def _mpd_kalman(tracks: list[PeerTrack], n: int, settings: Mapping[str, Any]) -> _Raw:
    mpd = require("movingpandas", "detector 'movingpandas-kalman'")
    require("stonesoup", "detector 'movingpandas-kalman'")
    raw = np.zeros(n)
    lat_c = np.full(n, math.nan)
    lon_c = np.full(n, math.nan)
    if not tracks:
        return raw, lat_c, lon_c
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        tc = _collection(tracks)
        smooth = mpd.KalmanSmootherCV(tc).smooth(
            process_noise_std=float(settings["process_noise_std"]),
            measurement_noise_std=float(settings["measurement_noise_std"]),
        )
    for tr, traj in zip(tracks, smooth.trajectories, strict=True):
        geom = traj.df.geometry
        la = geom.y.to_numpy(dtype=np.float64)
        lo = geom.x.to_numpy(dtype=np.float64)
        rows = traj.df["row"].to_numpy(dtype=np.int64)
        order = {int(r): i for i, r in enumerate(tr.rows)}
        idx = np.array([order[int(r)] for r in rows], dtype=np.int64)
        e, no = tr.frame.to_local(la, lo)
        raw[rows] = np.hypot(e - tr.east[idx], no - tr.north[idx])
        lat_c[rows], lon_c[rows] = la, lo
    return raw, lat_c, lon_c


def _pyod(tracks: list[PeerTrack], n: int, settings: Mapping[str, Any], variant: str) -> _Raw:
    iforest = require("pyod.models.iforest", "detector 'pyod-iforest'")
    raw = np.zeros(n)
    rows_all, feats = [], []
    for tr in tracks:
        f = _Features(variant == "+speed+heading")
        for i, row in enumerate(tr.rows):
            x = f.update(
                float(tr.t[i]),
                float(tr.east[i]),
                float(tr.north[i]),
                _value(tr.speed, i),
                _value(tr.heading, i),
            )
            x.pop("accel")
            feats.append(list(x.values()))
            rows_all.append(row)
    if len(feats) >= 2:
        model = iforest.IForest(
            contamination=float(settings["contamination"]),
            n_estimators=int(settings["n_estimators"]),
            random_state=0,
        )
        model.fit(np.asarray(feats, dtype=np.float64))
        # labels_ are 0/1 on the data it was fitted on; the raw score is that label.
        raw[np.asarray(rows_all)] = np.asarray(model.labels_, dtype=np.float64)
    return _dropped(tracks, raw, n)


#: Seconds scikit-mobility's own ``filter`` call took in the last ``skmob-filter`` run
#: (without starting its environment's Python), for timing it fairly.
SKMOB_LAST_SECONDS: list[float] = []


def _skmob(tracks: list[PeerTrack], n: int, settings: Mapping[str, Any]) -> _Raw:
    from .skmob_peer import skmob_kept

    raw = np.zeros(n)
    if tracks:
        kept, seconds = skmob_kept(
            [(tr.rows, tr.t, tr.lat, tr.lon) for tr in tracks],
            [float(settings["max_speed_kmh"])],
        )
        SKMOB_LAST_SECONDS[:] = seconds
        raw[np.concatenate([tr.rows for tr in tracks])] = 1.0
        raw[kept[0]] = 0.0
    return _dropped(tracks, raw, n)


def peer_raw(
    name: str, fixes: pd.DataFrame, settings: Mapping[str, Any], variant: str | None = None
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Run a peer once: per row the raw score, ``lat_clean``, ``lon_clean``, ``invalid_reason``.

    A row is flagged where its raw score exceeds the peer's threshold
    (``settings["threshold"]``, or ``gate`` for the Kalman peers); the raw
    score does not depend on the threshold except for the gated Kalman
    filters, so a threshold can be tuned from one run.
    """
    _check_name(name)
    variant = variant_of(fixes) if variant is None else variant
    tracks, reason = peer_tracks(fixes, variant)
    n = len(fixes)
    if name in _STREAMS:
        raw, la, lo = _from_streams(name, tracks, n, settings, variant)
    elif name == "hampel":
        raw, la, lo = _hampel(tracks, n, settings)
    elif name == "movingpandas-outlier":
        raw, la, lo = _mpd_outlier(tracks, n, settings)
    elif name == "movingpandas-kalman":
        raw, la, lo = _mpd_kalman(tracks, n, settings)
    elif name == "pyod-iforest":
        raw, la, lo = _pyod(tracks, n, settings, variant)
    else:
        raw, la, lo = _skmob(tracks, n, settings)
    return raw, la, lo, reason


def threshold_of(name: str, settings: Mapping[str, Any]) -> float:
    """The threshold a peer's raw score is compared with."""
    if name in ("kalman-chi2", "kalman-chi2-vel"):
        return float(settings["gate"])
    if name == "pyod-iforest":
        return 0.5
    return float(settings["threshold"])


class PeerDetector:
    """A peer behind the batch detector interface, with settings per input variant.

    ``settings``: ``{variant: {setting: value}}`` (missing variants and keys
    fall back to :data:`DEFAULT_SETTINGS`). The variant is read off the
    fixes (:func:`variant_of`) unless ``variant`` fixes it.
    """

    def __init__(
        self,
        name: str,
        settings: Mapping[str, Mapping[str, Any]] | None = None,
        variant: str | None = None,
    ) -> None:
        self.name = name
        self.settings = settings
        self.variant = variant

    def settings_for(self, variant: str) -> dict[str, Any]:
        """The settings this detector uses on fixes of ``variant``."""
        _check_name(self.name)
        given = (self.settings or {}).get(variant, {})
        return {**DEFAULT_SETTINGS[self.name], **given}

    def detect(self, fixes: pd.DataFrame) -> pd.DataFrame:
        """One result row per input row (docs/architecture.md, "Detector interface")."""
        _check_name(self.name)
        if self.name in _MODULES:
            require(_MODULES[self.name], f"detector {self.name!r}")
        variant = self.variant or variant_of(fixes)
        settings = self.settings_for(variant)
        raw, la, lo, reason = peer_raw(self.name, fixes, settings, variant)
        thr = threshold_of(self.name, settings)
        flag = raw > thr
        score = np.array([_score(float(r), thr) for r in raw])
        score[reason != ""] = math.nan
        return result_frame(
            fixes.index, reason, anomaly=flag, score=score, lat_clean=la, lon_clean=lo
        )

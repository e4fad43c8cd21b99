"""Prototype: the offset tracker as a stated model, a switching Kalman filter searched by beam.

Per channel (east, north), the fix is ``z = p + o + e``: ``p`` the clean track
(constant velocity, white acceleration noise ``sigma_a``), ``e`` the receiver's
noise (``sigma_m``), and the fault in one of three modes:

* ``clean``: ``o = 0``; the fix updates the clean track;
* ``jump``: ``o`` constant; the fix updates the clean track through ``z - o``
  (a jump's fixes move like the real track);
* ``noise``: the fix is unrelated to the track (an outlier); the track coasts.

Mode changes per fix: clean -> jump ``p_jump`` (its offset uniform over
+-``span_m``), clean -> noise ``p_noise``; a fault ends (-> clean) with hazard
``dt / tau_s``; jump -> noise / new jump and noise -> jump ``p_switch``; noise ->
noise ``p_noise_stay``. Any mode may also ``restart``: the clean track was wrong
and starts again on the fix (``p_restart``). Each hypothesis carries its Kalman
state and log-weight; the ``beam`` best survive, always including the best of each
mode, duplicates merged. Read off: the best hypothesis's offset (``o`` in a jump,
``z - p`` in noise, 0 when clean).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

CLEAN, JUMP, NOISE = 0.0, 1.0, 2.0
# h: [p, v, P00, P01, P11, o, age, logw, mode]


@dataclass(frozen=True)
class HypParams:
    sigma_a: float = 1.5
    sigma_m: float = 4.0
    p_jump: float = 0.005
    p_noise: float = 0.01
    p_switch: float = 0.05
    p_noise_stay: float = 0.7
    span_m: float = 100.0
    tau_s: float = 30.0
    p_restart: float = 1e-4
    beam: int = 12
    v0_sigma: float = 15.0


def _predict(h: np.ndarray, dt: float, q: float) -> None:
    p, v, a, b, c = h[0], h[1], h[2], h[3], h[4]
    h[0] = p + v * dt
    h[2] = a + 2 * dt * b + dt * dt * c + q * dt**4 / 4
    h[3] = b + dt * c + q * dt**3 / 2
    h[4] = c + q * dt * dt


def _update(h: np.ndarray, y: float, r: float) -> float:
    """Kalman update with measurement ``y`` of p; returns the log-likelihood of ``y``."""
    s = h[2] + r
    k0, k1 = h[2] / s, h[3] / s
    nu = y - h[0]
    h[0] += k0 * nu
    h[1] += k1 * nu
    a, b, c = h[2], h[3], h[4]
    h[2] = (1 - k0) * a
    h[3] = (1 - k0) * b
    h[4] = c - k1 * b
    return -0.5 * math.log(2 * math.pi * s) - 0.5 * nu * nu / s


def channel_offsets(dt: np.ndarray, z: np.ndarray, prm: HypParams) -> np.ndarray:
    """Per fix: [offset, innovation over its spread (best hyp, before), |z - p_pred|, age, evidence]."""
    q = prm.sigma_a**2
    r = prm.sigma_m**2
    out = np.zeros((len(z), 5))
    hyps = [np.array([z[0], 0.0, r, 0.0, prm.v0_sigma**2, 0.0, 0.0, 0.0, CLEAN])]
    log_u = -math.log(2 * prm.span_m)
    for i in range(1, len(z)):
        d = float(dt[i])
        end = min(d / prm.tau_s, 0.5)
        children: list[np.ndarray] = []
        best_parent = hyps[0]
        bp = best_parent.copy()
        _predict(bp, d, q)
        out_nu = (z[i] - bp[5] - bp[0]) / math.sqrt(bp[2] + r)
        out_dist = abs(z[i] - bp[0])
        for h in hyps:
            hp = h.copy()
            _predict(hp, d, q)
            mode = hp[8]
            if mode == CLEAN:
                to_clean, to_jump, to_noise, stay_jump = 1 - prm.p_jump - prm.p_noise, prm.p_jump, prm.p_noise, 0.0
            elif mode == JUMP:
                to_clean, to_jump, to_noise = end, prm.p_switch, prm.p_switch
                stay_jump = 1 - end - 2 * prm.p_switch
            else:
                to_clean, to_jump, to_noise, stay_jump = end, prm.p_switch, prm.p_noise_stay, 0.0
                to_clean = 1 - prm.p_switch - prm.p_noise_stay
            # -> clean
            c = hp.copy()
            c[7] += math.log(to_clean) + _update(c, z[i], r)
            c[5], c[6], c[8] = 0.0, 0.0, CLEAN
            children.append(c)
            if stay_jump > 0:  # the jump goes on
                k = hp.copy()
                k[7] += math.log(stay_jump) + _update(k, z[i] - k[5], r)
                k[6] += d
                children.append(k)
            # -> a new jump: the fix sets the offset, says nothing of p
            n = hp.copy()
            n[5], n[7], n[8] = z[i] - n[0], n[7] + math.log(to_jump) + log_u, JUMP
            n[6] = n[6] + d if mode != CLEAN else d
            children.append(n)
            # -> noise: the fix says nothing of p
            s = hp.copy()
            s[5], s[7], s[8] = z[i] - s[0], s[7] + math.log(to_noise) + log_u, NOISE
            s[6] = s[6] + d if mode != CLEAN else d
            children.append(s)
        rs = bp.copy()  # restart: the clean track was wrong
        rs[0], rs[2], rs[3] = z[i], r, 0.0
        rs[4] = max(rs[4], prm.v0_sigma**2)
        rs[5], rs[6], rs[8] = 0.0, 0.0, CLEAN
        rs[7] = best_parent[7] + math.log(prm.p_restart) + log_u
        children.append(rs)
        children.sort(key=lambda h: -h[7])
        kept: list[np.ndarray] = []
        modes_seen: set[float] = set()
        for ch in children:
            if any(
                ch[8] == o[8] and abs(ch[0] - o[0]) < 0.05 and abs(ch[5] - o[5]) < 0.05
                and abs(ch[1] - o[1]) < 0.05 for o in kept
            ):
                continue
            if len(kept) < prm.beam - 3 or ch[8] not in modes_seen:
                kept.append(ch)
                modes_seen.add(ch[8])
            if len(kept) >= prm.beam:
                break
        kept.sort(key=lambda h: -h[7])
        top = kept[0][7]
        for h in kept:
            h[7] -= top
        hyps = kept
        best = hyps[0]
        zero = max((h[7] for h in hyps if h[8] == CLEAN), default=-50.0)
        out[i] = (best[5] if best[8] != CLEAN else 0.0, out_nu, out_dist, best[6], -zero)
    return out


def offsets(dt: np.ndarray, east: np.ndarray, north: np.ndarray, prm: HypParams) -> np.ndarray:
    """Per fix: offset east, north (m)."""
    return np.stack(
        [channel_offsets(dt, east, prm)[:, 0], channel_offsets(dt, north, prm)[:, 0]], 1
    )

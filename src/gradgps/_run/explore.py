"""The report's explorable track view: one inline SVG per track, a selector, zoom and hover.

Still one self-contained file: the drawing is inline SVG built here, the
behaviour a small inline script (no library, no network). Per track: the
fixes as received (grey line), the repaired track (green line) and every
flagged fix as a dot coloured by bias type whose tooltip (SVG ``<title>``,
shown on hover by any browser, script or not) gives row, time, score, bias
and time type. Positions are metres east/north of the track's first usable
fix, so a 10-hour drive and a car park are both drawn to their own extent.

The script: a ``<select>`` shows one track at a time; the mouse wheel or the
+/- buttons zoom around the pointer or the centre, dragging pans, "reset"
restores the view; ``<time data-t>`` elements (events table) are rewritten in
the viewer's local time, the UTC time kept as their tooltip. The page's
address may carry a view, ``report.html#track=3&zoom=4``, opened as given
(and used by the headless-browser test).
"""

from __future__ import annotations

import html
import math

import numpy as np
import pandas as pd

from .._tracks.geo import LocalFrame

__all__ = ["SCRIPT", "track_explorer"]

#: Lines are decimated to this many vertices per track; flagged dots are capped too.
MAX_LINE_VERTICES = 4_000
MAX_DOTS = 5_000
#: Tracks offered in the selector (the rest are in the CSV and the static figure).
MAX_TRACKS = 500
_COLOURS = {"noise": "#d62728", "jump": "#1f77b4", "drift": "#9467bd", "offset": "#ff7f0e"}


def _utc(t: float) -> str:
    if not math.isfinite(t):
        return ""
    if abs(t) < 1e8:
        return f"{t:,.1f} s"
    return pd.Timestamp(t, unit="s", tz="UTC").strftime("%Y-%m-%d %H:%M:%S UTC")


def _path(x: np.ndarray, y: np.ndarray) -> str:
    step = max(1, math.ceil(x.size / MAX_LINE_VERTICES))
    keep = np.r_[np.arange(0, x.size, step), x.size - 1] if x.size else np.arange(0)
    return " ".join(f"{a:.1f},{b:.1f}" for a, b in zip(x[keep], y[keep], strict=True))


def _track_svg(name: str, k: int, fixes: pd.DataFrame, result: pd.DataFrame) -> str:
    lat = fixes["lat"].to_numpy(np.float64)
    lon = fixes["lon"].to_numpy(np.float64)
    lat_c = result["lat_clean"].to_numpy(np.float64)
    lon_c = result["lon_clean"].to_numpy(np.float64)
    frame = LocalFrame(float(lat[0]), float(lon[0]))
    east, north = frame.to_local(lat, lon)
    ok_c = np.isfinite(lat_c) & np.isfinite(lon_c)
    east_c, north_c = frame.to_local(np.where(ok_c, lat_c, lat), np.where(ok_c, lon_c, lon))
    xs = np.r_[east, east_c[ok_c]]
    ys = np.r_[north, north_c[ok_c]]
    x0, x1 = float(xs.min()), float(xs.max())
    y0, y1 = float(ys.min()), float(ys.max())
    span = max(x1 - x0, y1 - y0, 10.0)
    pad = 0.04 * span
    view = f"{x0 - pad:.1f} {-y1 - pad:.1f} {x1 - x0 + 2 * pad:.1f} {y1 - y0 + 2 * pad:.1f}"
    radius = span / 250.0
    flagged = np.flatnonzero(result["anomaly"].to_numpy() == 1)[:MAX_DOTS]
    rows = fixes.index.to_numpy()
    t = fixes["t"].to_numpy(np.float64)
    score = result["score"].to_numpy(np.float64)
    bias = result["bias_type"].to_numpy(object)
    time_type = result["time_type"].to_numpy(object)
    dots = []
    for i in flagged.tolist():
        colour = _COLOURS.get(str(bias[i]), "#555555")
        tip = f"row {rows[i]}, {_utc(t[i])}\nscore {score[i]:.3f}, {bias[i]} / {time_type[i]}"
        dots.append(
            f"<circle cx='{east[i]:.1f}' cy='{-north[i]:.1f}' r='{radius:.2f}' "
            f"fill='{colour}'><title>{html.escape(tip)}</title></circle>"
        )
    hidden = "" if k == 0 else " hidden"
    return (
        f"<div class='track-view' data-track='{html.escape(name)}'{hidden}>"
        f"<svg class='track-svg' viewBox='{view}' data-view='{view}' data-r='{radius:.3f}' "
        "preserveAspectRatio='xMidYMid meet' role='img' "
        f"aria-label='track {html.escape(name)}'>"
        f"<polyline class='raw' points='{_path(east, -north)}' fill='none' stroke='#999' "
        "stroke-width='1' vector-effect='non-scaling-stroke'/>"
        f"<polyline class='clean' points='{_path(east_c[ok_c], -north_c[ok_c])}' fill='none' "
        "stroke='#2ca02c' stroke-width='1.5' vector-effect='non-scaling-stroke'/>"
        + "".join(dots)
        + f"</svg><p class='muted'>track {html.escape(name)}: {len(fixes):,} usable fixes, "
        f"{flagged.size:,} flagged (dots; hover for the verdict)</p></div>"
    )


def track_explorer(fixes: pd.DataFrame, result: pd.DataFrame) -> str:
    """The explorable view (see the module docstring) as an HTML fragment; '' when nothing to draw."""
    usable = (result["invalid_reason"].to_numpy() == "") & np.isfinite(
        fixes["lat"].to_numpy(np.float64)
    )
    if not usable.any():
        return ""
    tracks = fixes["track"].astype(str).to_numpy(object)
    names = [str(n) for n in pd.unique(tracks[usable])][:MAX_TRACKS]
    views = []
    options = []
    for k, name in enumerate(names):
        rows = np.flatnonzero(usable & (tracks == name))
        views.append(_track_svg(name, k, fixes.iloc[rows], result.iloc[rows]))
        options.append(f"<option value='{html.escape(name)}'>{html.escape(name)}</option>")
    more = (
        f" (the first {MAX_TRACKS} of {len(pd.unique(tracks[usable])):,})"
        if len(names) == MAX_TRACKS
        else ""
    )
    return (
        "<div id='explorer'><p>"
        f"<label>track{more} <select id='track-select'>{''.join(options)}</select></label> "
        "<button type='button' id='zoom-in'>+</button>"
        "<button type='button' id='zoom-out'>&minus;</button>"
        "<button type='button' id='zoom-reset'>reset</button> "
        "<span class='muted'>wheel to zoom, drag to pan; grey: as received, green: "
        "repaired, dots: flagged fixes coloured by bias type</span></p>" + "".join(views) + "</div>"
    )


SCRIPT = """
(function () {
  "use strict";
  function views() { return Array.prototype.slice.call(document.querySelectorAll(".track-view")); }
  function current() { return views().filter(function (v) { return !v.hidden; })[0]; }
  function box(svg) { return svg.getAttribute("viewBox").split(" ").map(Number); }
  function setBox(svg, b) {
    svg.setAttribute("viewBox", b.map(function (v) { return v.toFixed(2); }).join(" "));
    var home = svg.getAttribute("data-view").split(" ").map(Number);
    var r = Number(svg.getAttribute("data-r")) * b[2] / home[2];
    svg.querySelectorAll("circle").forEach(function (c) { c.setAttribute("r", r.toFixed(3)); });
  }
  function zoom(svg, factor, cx, cy) {
    var b = box(svg);
    if (cx === undefined) { cx = b[0] + b[2] / 2; cy = b[1] + b[3] / 2; }
    setBox(svg, [cx - (cx - b[0]) / factor, cy - (cy - b[1]) / factor, b[2] / factor, b[3] / factor]);
  }
  function show(name) {
    views().forEach(function (v) { v.hidden = v.getAttribute("data-track") !== name; });
    var select = document.getElementById("track-select");
    if (select) { select.value = name; }
  }
  function toPoint(svg, ev) {
    var b = box(svg), r = svg.getBoundingClientRect();
    var s = Math.max(b[2] / r.width, b[3] / r.height);
    var ox = b[0] + b[2] / 2 - s * r.width / 2, oy = b[1] + b[3] / 2 - s * r.height / 2;
    return [ox + (ev.clientX - r.left) * s, oy + (ev.clientY - r.top) * s, s];
  }
  var select = document.getElementById("track-select");
  if (select) { select.addEventListener("change", function () { show(select.value); }); }
  [["zoom-in", 2], ["zoom-out", 0.5]].forEach(function (p) {
    var b = document.getElementById(p[0]);
    if (b) { b.addEventListener("click", function () { zoom(current().querySelector("svg"), p[1]); }); }
  });
  var reset = document.getElementById("zoom-reset");
  if (reset) {
    reset.addEventListener("click", function () {
      var svg = current().querySelector("svg");
      setBox(svg, svg.getAttribute("data-view").split(" ").map(Number));
    });
  }
  document.querySelectorAll(".track-svg").forEach(function (svg) {
    svg.addEventListener("wheel", function (ev) {
      ev.preventDefault();
      var p = toPoint(svg, ev);
      zoom(svg, ev.deltaY < 0 ? 1.25 : 0.8, p[0], p[1]);
    }, { passive: false });
    var drag = null;
    svg.addEventListener("mousedown", function (ev) { drag = toPoint(svg, ev); });
    window.addEventListener("mouseup", function () { drag = null; });
    svg.addEventListener("mousemove", function (ev) {
      if (!drag) { return; }
      var p = toPoint(svg, ev), b = box(svg);
      setBox(svg, [b[0] - (p[0] - drag[0]), b[1] - (p[1] - drag[1]), b[2], b[3]]);
    });
  });
  document.querySelectorAll("time[data-t]").forEach(function (el) {
    var t = Number(el.getAttribute("data-t"));
    if (!isFinite(t) || Math.abs(t) < 1e8) { return; }
    el.title = el.textContent;
    el.textContent = new Date(t * 1000).toLocaleString(undefined, {
      year: "numeric", month: "short", day: "numeric",
      hour: "2-digit", minute: "2-digit", second: "2-digit", hour12: false, timeZoneName: "short"
    });
  });
  var hash = {};
  location.hash.replace(/^#/, "").split("&").forEach(function (kv) {
    var i = kv.indexOf("=");
    if (i > 0) { hash[decodeURIComponent(kv.slice(0, i))] = decodeURIComponent(kv.slice(i + 1)); }
  });
  if (hash.track !== undefined) { show(hash.track); }
  if (hash.zoom && current()) { zoom(current().querySelector("svg"), Number(hash.zoom) || 1); }
  document.documentElement.setAttribute("data-ready", "1");
})();
"""

"""The report's explorable track view: one inline SVG per track, a selector, zoom and hover.

Still one self-contained file: the drawing is inline SVG, the behaviour a
small inline script (no library, no network). Per track: the fixes as
received (grey line, drawn here), and, drawn by the script from the GeoJSON
document embedded in the page (:func:`embedded_geojson`, the very document
``gradgps detect --geojson`` writes, built by
:func:`gradgps._io.export.geojson_document`): the repaired track (its
``"repaired track"`` lines, green) and every ``"flagged fix"`` point as a
dot coloured by bias type whose tooltip (SVG ``<title>``) gives row, time,
score, bias and time type and the repaired position. Positions are metres
east/north of the track's first usable fix (the tangent plane of
:class:`gradgps._tracks.geo.LocalFrame`, computed the same way in the
script), so a 10-hour drive and a car park are both drawn to their own extent.
A one-fix "repaired track" (a Point) is no line and is not drawn; features of
tracks past :data:`MAX_TRACKS` have no view and are not drawn either.

The script: a ``<select>`` shows one track at a time; the mouse wheel or the
+/- buttons zoom around the pointer or the centre, dragging pans, "reset"
restores the view; ``<time data-t>`` elements (events table) are rewritten in
the viewer's local time, the UTC time kept as their tooltip. The page's
address may carry a view, ``report.html#track=3&zoom=4``, opened as given
(used by the headless-browser test). When done it says on
``#explorer`` how many GeoJSON lines and points it drew
(``data-geojson-drawn="lines,points"``).

Size: the embedded document is the exporter's text (``<``, ``>``, ``&`` as JSON escapes) up to
:data:`MAX_EMBEDDED_CHARS`; a larger one (a long or dense file) is embedded
thinned (:func:`thin_document`): each track's repaired lines to at most
:data:`MAX_LINE_VERTICES` vertices, its flagged fixes to at most
:data:`MAX_DOTS` points evenly spread, event lines likewise, coordinates
rounded to 7 decimals (about 1 cm); the page says so, and ``--geojson``
writes the whole document.
"""

from __future__ import annotations

import html
import json
import math
from typing import Any

import numpy as np
import pandas as pd

from .._io.export import geojson_text
from .._tracks.geo import LocalFrame

__all__ = [
    "COLOURS",
    "MAX_EMBEDDED_CHARS",
    "SCRIPT",
    "embedded_geojson",
    "thin_document",
    "track_explorer",
]

#: The as-received line is decimated to this many vertices per track, and so are the repaired
#: lines of a thinned embedded document; its flagged fixes are capped per track too.
MAX_LINE_VERTICES = 4_000
MAX_DOTS = 5_000
#: The embedded GeoJSON is the exporter's text up to this size, thinned beyond it.
MAX_EMBEDDED_CHARS = 3_000_000
#: Tracks offered in the selector (the rest are in the CSV and the static figure).
MAX_TRACKS = 500
#: Dot colours by bias type (anything else is grey); the repaired line's colour.
COLOURS = {"noise": "#d62728", "jump": "#1f77b4", "drift": "#9467bd", "offset": "#ff7f0e"}
CLEAN_COLOUR = "#2ca02c"


def _path(x: np.ndarray, y: np.ndarray) -> str:
    step = max(1, math.ceil(x.size / MAX_LINE_VERTICES))
    keep = np.r_[np.arange(0, x.size, step), x.size - 1] if x.size else np.arange(0)
    return " ".join(f"{a:.1f},{b:.1f}" for a, b in zip(x[keep], y[keep], strict=True))


def _thin_line(coords: list[list[float]], step: int) -> list[list[float]]:
    """Every ``step``-th vertex and the last one, rounded to 7 decimals (about 1 cm)."""
    kept = coords[::step]
    if (len(coords) - 1) % step:
        kept.append(coords[-1])
    return [[round(c[0], 7), round(c[1], 7)] for c in kept]


def _parts(geometry: dict[str, Any] | None) -> list[list[list[float]]]:
    if geometry is None:
        return []
    if geometry["type"] == "LineString":
        return [geometry["coordinates"]]
    if geometry["type"] == "MultiLineString":
        return list(geometry["coordinates"])
    return []


def _thin_geometry(geometry: dict[str, Any] | None, step: int) -> dict[str, Any] | None:
    if geometry is None:
        return None
    if geometry["type"] == "Point":
        x, y = geometry["coordinates"]
        return {"type": "Point", "coordinates": [round(x, 7), round(y, 7)]}
    if geometry["type"] == "LineString":
        return {"type": "LineString", "coordinates": _thin_line(geometry["coordinates"], step)}
    if geometry["type"] == "MultiLineString":
        parts = [_thin_line(part, step) for part in geometry["coordinates"]]
        return {"type": "MultiLineString", "coordinates": parts}
    return geometry


def thin_document(doc: dict[str, Any]) -> dict[str, Any]:
    """A smaller copy of a :func:`gradgps._io.export.geojson_document` for the report.

    Per track, the ``"repaired track"`` lines keep every k-th vertex (and each
    line's ends) so that at most about :data:`MAX_LINE_VERTICES` remain, the
    ``"flagged fix"`` points at most :data:`MAX_DOTS`, evenly spread over the
    track; each ``"event"`` line is thinned the same way. Properties are kept
    as they are; coordinates are rounded to 7 decimals. Still RFC 7946.
    """
    features: list[dict[str, Any]] = doc["features"]
    vertices: dict[Any, int] = {}
    flagged: dict[Any, int] = {}
    for ft in features:
        props = ft.get("properties") or {}
        if props.get("kind") == "repaired track":
            n = sum(len(p) for p in _parts(ft["geometry"]))
            vertices[props.get("track")] = vertices.get(props.get("track"), 0) + n
        elif props.get("kind") == "flagged fix":
            flagged[props.get("track")] = flagged.get(props.get("track"), 0) + 1
    keep_dots = {
        track: set(np.unique(np.linspace(0, n - 1, MAX_DOTS).round().astype(int)).tolist())
        for track, n in flagged.items()
        if n > MAX_DOTS
    }
    seen: dict[Any, int] = {}
    out: list[dict[str, Any]] = []
    for ft in features:
        props = ft.get("properties") or {}
        kind, track = props.get("kind"), props.get("track")
        if kind == "flagged fix":
            k = seen.get(track, 0)
            seen[track] = k + 1
            if track in keep_dots and k not in keep_dots[track]:
                continue
            step = 1
        elif kind == "repaired track":
            step = max(1, math.ceil(vertices[track] / MAX_LINE_VERTICES))
        else:
            n = sum(len(p) for p in _parts(ft.get("geometry")))
            step = max(1, math.ceil(n / MAX_LINE_VERTICES))
        out.append({**ft, "geometry": _thin_geometry(ft.get("geometry"), step)})
    return {**doc, "features": out}


def embedded_geojson(doc: dict[str, Any], *, thinned: bool = False) -> tuple[str, str]:
    """The ``<script type="application/geo+json" id="geojson">`` element and a sentence on it.

    Its text is :func:`gradgps._io.export.geojson_text` of ``doc`` (of
    :func:`thin_document` beyond :data:`MAX_EMBEDDED_CHARS`), with ``<``,
    ``>`` and ``&`` written as JSON escapes: they can only occur inside JSON
    strings (a track id, a label), where ``\\u003c`` means the same, and a
    ``</script>`` in a track id can then never end the element. ``thinned``: ``doc``
    is already built from a thinned sample (:mod:`gradgps._run.report_data`).
    """
    text = geojson_text(doc)
    if len(text) > MAX_EMBEDDED_CHARS:
        text = geojson_text(thin_document(doc))
        thinned = True
    if thinned:
        note = (
            "The repaired lines and flagged fixes are drawn from a thinned copy of the "
            f"GeoJSON embedded in this page (at most {MAX_LINE_VERTICES:,} line vertices and "
            f"{MAX_DOTS:,} flagged fixes per track); gradgps detect --geojson writes every fix."
        )
    else:
        note = (
            "The repaired lines and flagged fixes are drawn from the GeoJSON embedded in "
            "this page, the same document gradgps detect --geojson writes."
        )
    safe = text.replace("&", "\\u0026").replace("<", "\\u003c").replace(">", "\\u003e")
    attr = " data-thinned='1'" if thinned else ""
    return f"<script type='application/geo+json' id='geojson'{attr}>{safe}</script>", note


def _track_svg(
    name: str,
    k: int,
    fixes: pd.DataFrame,
    result: pd.DataFrame,
    counts: tuple[int, int] | None = None,
) -> str:
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
    usable = len(fixes) if counts is None else counts[0]
    flagged = int((result["anomaly"].to_numpy() == 1).sum()) if counts is None else counts[1]
    hidden = "" if k == 0 else " hidden"
    return (
        f"<div class='track-view' data-track='{html.escape(name)}'{hidden}>"
        f"<svg class='track-svg' viewBox='{view}' data-view='{view}' data-r='{radius:.3f}' "
        f"data-origin='{frame.lat0!r} {frame.lon0!r}' "
        "preserveAspectRatio='xMidYMid meet' role='img' "
        f"aria-label='track {html.escape(name)}'>"
        f"<polyline class='raw' points='{_path(east, -north)}' fill='none' stroke='#999' "
        "stroke-width='1' vector-effect='non-scaling-stroke'/>"
        f"</svg><p class='muted'>track {html.escape(name)}: {usable:,} usable fixes, "
        f"{flagged:,} flagged (dots; hover for the verdict)</p></div>"
    )


def track_explorer(
    fixes: pd.DataFrame,
    result: pd.DataFrame,
    note: str = "",
    counts: dict[str, tuple[int, int]] | None = None,
) -> str:
    """The explorable view (see the module docstring) as an HTML fragment; '' when nothing to draw.

    ``note`` (from :func:`embedded_geojson`) says what the script draws from;
    ``counts``: per track, its usable and flagged fixes, where ``fixes`` is a thinned
    sample of the run (:mod:`gradgps._run.report_data`).
    """
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
        shown = None if counts is None else counts.get(name, (rows.size, 0))
        views.append(_track_svg(name, k, fixes.iloc[rows], result.iloc[rows], shown))
        options.append(f"<option value='{html.escape(name)}'>{html.escape(name)}</option>")
    more = (
        f" (the first {MAX_TRACKS} of {len(pd.unique(tracks[usable])):,})"
        if len(names) == MAX_TRACKS
        else ""
    )
    colours = html.escape(json.dumps({**COLOURS, "clean": CLEAN_COLOUR}))
    return (
        f"<div id='explorer' data-colours='{colours}'><p>"
        f"<label>track{more} <select id='track-select'>{''.join(options)}</select></label> "
        "<button type='button' id='zoom-in'>+</button>"
        "<button type='button' id='zoom-out'>&minus;</button>"
        "<button type='button' id='zoom-reset'>reset</button> "
        "<span class='muted'>wheel to zoom, drag to pan; grey: as received, green: "
        "repaired, dots: flagged fixes coloured by bias type. "
        f"{html.escape(note)}</span></p>" + "".join(views) + "</div>"
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
  // The embedded GeoJSON (the --geojson document): repaired lines and flagged fixes, drawn into
  // each track's view in its own tangent plane (LocalFrame: WGS84 ECEF, east/north axes).
  function ecef(latDeg, lonDeg) {
    var a = 6378137.0, f = 1 / 298.257223563, e2 = f * (2 - f);
    var lat = latDeg * Math.PI / 180, lon = lonDeg * Math.PI / 180, s = Math.sin(lat);
    var n = a / Math.sqrt(1 - e2 * s * s);
    return [n * Math.cos(lat) * Math.cos(lon), n * Math.cos(lat) * Math.sin(lon), n * (1 - e2) * s];
  }
  function frameOf(svg) {
    var o = svg.getAttribute("data-origin").split(" ").map(Number);
    var lat = o[0] * Math.PI / 180, lon = o[1] * Math.PI / 180;
    var sl = Math.sin(lat), cl = Math.cos(lat), so = Math.sin(lon), co = Math.cos(lon);
    return { o: ecef(o[0], o[1]), e: [-so, co], n: [-sl * co, -sl * so, cl] };
  }
  function toSvg(f, c) {
    var p = ecef(c[1], c[0]), dx = p[0] - f.o[0], dy = p[1] - f.o[1], dz = p[2] - f.o[2];
    var east = dx * f.e[0] + dy * f.e[1], north = dx * f.n[0] + dy * f.n[1] + dz * f.n[2];
    return east.toFixed(1) + "," + (-north).toFixed(1);
  }
  function tip(p) {
    var when = p.t !== null && Math.abs(p.t) < 1e8 ? p.t.toFixed(1) + " s"  // a relative clock
      : (p.time ? p.time.replace("T", " ").replace("Z", " UTC") : "");
    var text = "row " + p.row + ", " + when + "\\nscore " +
      (p.score === null ? "?" : p.score.toFixed(3)) + ", " + (p.bias_type || "?") + " / " + (p.time_type || "?");
    if (p.lat_clean !== null && p.lon_clean !== null) {
      text += "\\nrepaired to " + p.lat_clean.toFixed(6) + ", " + p.lon_clean.toFixed(6);
    }
    return p.alert ? text + "\\nalert (permanent fault)" : text;
  }
  var explorer = document.getElementById("explorer");
  var geo = document.getElementById("geojson");
  if (explorer && geo) {
    var ns = "http://www.w3.org/2000/svg", colours = JSON.parse(explorer.getAttribute("data-colours"));
    var svgs = {}, frames = {}, lines = 0, points = 0;
    views().forEach(function (v) { svgs[v.getAttribute("data-track")] = v.querySelector("svg"); });
    JSON.parse(geo.textContent).features.forEach(function (ft) {
      var p = ft.properties || {}, g = ft.geometry, svg = svgs[p.track];
      if (!g || !svg) { return; }
      var f = frames[p.track] || (frames[p.track] = frameOf(svg));
      if (p.kind === "repaired track" && (g.type === "LineString" || g.type === "MultiLineString")) {
        (g.type === "LineString" ? [g.coordinates] : g.coordinates).forEach(function (part) {
          var el = document.createElementNS(ns, "polyline");
          el.setAttribute("class", "clean");
          el.setAttribute("points", part.map(function (c) { return toSvg(f, c); }).join(" "));
          el.setAttribute("fill", "none");
          el.setAttribute("stroke", colours.clean);
          el.setAttribute("stroke-width", "2");
          el.setAttribute("vector-effect", "non-scaling-stroke");
          svg.appendChild(el);
          lines++;
        });
      } else if (p.kind === "flagged fix" && g.type === "Point") {
        var xy = toSvg(f, g.coordinates).split(","), el = document.createElementNS(ns, "circle");
        el.setAttribute("cx", xy[0]);
        el.setAttribute("cy", xy[1]);
        el.setAttribute("r", svg.getAttribute("data-r"));
        el.setAttribute("fill", colours[p.bias_type] || "#555555");
        var title = document.createElementNS(ns, "title");
        title.textContent = tip(p);
        el.appendChild(title);
        svg.appendChild(el);
        points++;
      }
    });
    explorer.setAttribute("data-geojson-drawn", lines + "," + points);
  }
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

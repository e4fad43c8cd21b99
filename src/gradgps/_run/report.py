"""A detection run as one self-contained HTML file (and the same figures as PNGs).

Why one file: a report is mailed, attached to a ticket or opened on a laptop
in a car park; it must work offline and survive being moved. So the figures
are drawn with matplotlib into PNGs embedded as base64 ``data:`` URIs, the
styling is inline CSS, and nothing is fetched from the network (no CDN, no
map tiles). PNG rather than SVG: a 10,000-point track is 10,000 SVG path
nodes per line, a PNG costs the same whatever the number of points.

What it shows:

* **Summary**: points, usable fixes, anomalies by bias type and by time type,
  alerts, throughput, the model; plus any extra rows the caller adds (the
  demo adds its scores against the injected labels).
* **Track**: all fixes in local metres (east/north of one tangent plane),
  as received on the left with the anomalous fixes coloured by bias type and
  marked by time type, and the recovered track (``lat_clean``/``lon_clean``)
  on the right, on the same axes.
* **Channels**: per segment (the ones with the most anomalies), east and north
  over time as the distance from the REMA prediction, with the REMA bounds
  (the band a value must stay in) and the fixes the detector flagged. Plotting
  the raw coordinate instead would draw a ±5 m band on a kilometres-long ramp:
  invisible. The bounds are those of the model's own feature pipeline
  (:func:`gradgps._grad.core.core_step` with the model's parameters), so
  they are what the network saw, not a re-tuned lookalike. Note that the
  anomaly verdict is the network's, so a flagged fix can sit inside the band
  and vice versa.
* **Anomalies**: the first rows of the anomalous fixes, as a table.

The run's GeoJSON (the document ``--geojson`` writes) is embedded as a
``<script type="application/geo+json" id="geojson">`` data block, and the
explorable per-track view draws its repaired lines and flagged fixes
(:mod:`gradgps._run.explore`); the one executable script is the view's.
"""

from __future__ import annotations

import base64
import html
import io
import math
import warnings
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd
from numpy.typing import NDArray

from .._grad.defaults import grad_points
from .._grad.pipeline import PipelineParams, grad_features
from .._io.export import geojson_document
from .._result import ResultCounts
from .._tracks.geo import LocalFrame
from .._tracks.preprocess import Prepared, time_glitch_breaks
from .explore import SCRIPT, embedded_geojson, track_explorer
from .report_data import MAX_TABLE_ROWS, SAMPLE_ROWS, TRACK_ROWS, Thinned

__all__ = ["ChannelBounds", "ReportInputs", "figures", "rema_bounds", "write_plots", "write_report"]

FloatArray = NDArray[np.float64]

#: Colours of the bias types (anything else is grey) and markers of the time types.
BIAS_COLOURS = {"noise": "#d62728", "jump": "#1f77b4", "drift": "#9467bd", "offset": "#ff7f0e"}
TIME_MARKERS = {"transient": "o", "intermittent": "s", "permanent": "^", "none": "x"}
#: At most this many segments get a channel figure (the ones with the most anomalies).
MAX_CHANNEL_SEGMENTS = 3
#: Lines are decimated to at most this many vertices (markers are never dropped).
MAX_LINE_POINTS = 20_000


@dataclass(frozen=True)
class ChannelBounds:
    """REMA bounds of one segment: per point, east/north and their lower/upper bound (metres)."""

    segment: int
    track: str
    t: FloatArray
    east: FloatArray
    north: FloatArray
    east_lower: FloatArray
    east_upper: FloatArray
    north_lower: FloatArray
    north_upper: FloatArray
    flagged: NDArray[np.bool_]


@dataclass
class ReportInputs:
    """Everything a report draws: the fixes, the detector's result, and what ran."""

    fixes: pd.DataFrame
    result: pd.DataFrame
    params: PipelineParams
    title: str = "gradgps detection report"
    source: str = ""
    model: str = ""
    elapsed_s: float = math.nan
    extra_summary: Mapping[str, str] = field(default_factory=dict)
    events: pd.DataFrame | None = None
    #: Where the input is outside what the model was validated on (one sentence each).
    warnings: Sequence[str] = ()
    #: Each row's time as the output table writes it (the input's own text, see
    #: :mod:`gradgps._io.times`); ``None`` where the input's times are numbers,
    #: which the tables show as readable UTC instead.
    time_text: Sequence[str] | None = None
    #: The run's GeoJSON (:func:`gradgps._io.export.geojson_document`), when the caller built
    #: it already (``detect --geojson`` writes the same one); built from the above when None.
    geojson: dict[str, Any] | None = None
    #: A long run's thinned data (:mod:`gradgps._run.report_data`): then ``fixes``,
    #: ``result`` and ``time_text`` are its sample and the counts come from its totals.
    thinned: Thinned | None = None


def rema_bounds(
    prepared: Prepared,
    params: PipelineParams,
    point_flag: NDArray[np.bool_],
    segments: Sequence[int],
) -> list[ChannelBounds]:
    """REMA bounds on east and north for the given segments, as the model's pipeline computes them
    (:func:`gradgps._grad.pipeline.grad_features`: on a file without speed or
    heading, REMA runs on the motion model's velocity, as in the detector)."""
    pts = prepared.points
    nan = np.full(len(pts), np.nan)
    speed = pts["speed"].to_numpy(np.float64) if "speed" in pts else nan
    heading = pts["heading"].to_numpy(np.float64) if "heading" in pts else nan
    t_all = pts["t"].to_numpy(np.float64)
    lat_all = pts["lat"].to_numpy(np.float64)
    lon_all = pts["lon"].to_numpy(np.float64)
    east_all = pts["east"].to_numpy(np.float64)
    north_all = pts["north"].to_numpy(np.float64)
    wanted = set(segments)
    out = []
    for seg, sl in prepared.segment_slices():
        if seg not in wanted:
            continue
        t = t_all[sl]
        bounds = grad_features(
            params,
            prepared.segment_frames[seg],
            t,
            lat_all[sl],
            lon_all[sl],
            speed[sl],
            heading[sl],
        ).rema_bounds
        east, north = east_all[sl], north_all[sl]
        out.append(
            ChannelBounds(
                segment=seg,
                track=str(pts["track"].iloc[sl.start]),
                t=t,
                east=east,
                north=north,
                east_lower=bounds[:, 0],
                east_upper=bounds[:, 1],
                north_lower=bounds[:, 2],
                north_upper=bounds[:, 3],
                flagged=point_flag[sl],
            )
        )
    return out


def _decimate(n: int, limit: int = MAX_LINE_POINTS) -> NDArray[np.int64]:
    step = max(1, math.ceil(n / limit))
    return np.arange(0, n, step, dtype=np.int64)


def _track_figure(inputs: ReportInputs) -> Any:
    import matplotlib.pyplot as plt

    fixes, result = inputs.fixes, inputs.result
    valid = (result["invalid_reason"].to_numpy() == "") & np.isfinite(fixes["lat"].to_numpy())
    lat, lon = fixes["lat"].to_numpy(np.float64), fixes["lon"].to_numpy(np.float64)
    first = int(np.flatnonzero(valid)[0])
    frame = LocalFrame(float(lat[first]), float(lon[first]))
    east, north = frame.to_local(np.where(valid, lat, lat[first]), np.where(valid, lon, lon[first]))
    lat_c = result["lat_clean"].to_numpy(np.float64)
    lon_c = result["lon_clean"].to_numpy(np.float64)
    clean_ok = valid & np.isfinite(lat_c) & np.isfinite(lon_c)
    east_c, north_c = frame.to_local(
        np.where(clean_ok, lat_c, lat[first]), np.where(clean_ok, lon_c, lon[first])
    )
    tracks = fixes["track"].to_numpy(object)
    anomaly = valid & (result["anomaly"].to_numpy() == 1)
    bias = result["bias_type"].to_numpy(object)
    time_type = result["time_type"].to_numpy(object)
    # Height from the track's aspect ratio: equal axes in a fixed-size figure leave bands of white.
    span_e = float(np.ptp(east[valid])) or 1.0
    span_n = float(np.ptp(north[valid])) or 1.0
    height = min(12.0, max(3.5, 6.2 * span_n / span_e + 1.4))
    fig, axes = plt.subplots(
        1, 2, figsize=(13, height), sharex=True, sharey=True, layout="constrained"
    )
    totals = inputs.thinned.totals if inputs.thinned is not None else None
    shown = {
        "as received": int(valid.sum()) if totals is None else totals.drawn,
        "recovered": int(clean_ok.sum()) if totals is None else totals.recovered,
    }
    for ax, (e, nn, ok, name) in zip(
        axes,
        ((east, north, valid, "as received"), (east_c, north_c, clean_ok, "recovered")),
        strict=True,
    ):
        for track in pd.unique(tracks[ok]):
            idx = np.flatnonzero(ok & (tracks == track))
            keep = idx[_decimate(idx.size, MAX_LINE_POINTS // max(1, len(pd.unique(tracks))))]
            ax.plot(e[keep], nn[keep], color="#888888", lw=0.7, zorder=1)
        ax.set_title(f"{name} ({shown[name]:,} fixes)")
        ax.set_xlabel("east (m)")
        ax.set_aspect("equal", adjustable="box")
        ax.grid(True, lw=0.3, alpha=0.5)
    axes[0].set_ylabel("north (m)")
    ax = axes[0]
    for b in sorted(set(bias[anomaly])):
        for tt in sorted(set(time_type[anomaly & (bias == b)])):
            sel = anomaly & (bias == b) & (time_type == tt)
            count = int(sel.sum()) if totals is None else totals.markers.get((b, tt), 0)
            ax.scatter(
                east[sel],
                north[sel],
                s=14,
                c=BIAS_COLOURS.get(b, "#555555"),
                marker=TIME_MARKERS.get(tt, "D"),
                linewidths=0.8,
                zorder=3,
                label=f"{b} / {tt} ({count:,})",
            )
    if anomaly.any():
        ax.legend(title="bias / time type", fontsize=8, loc="best", framealpha=0.85)
    repaired = anomaly & clean_ok
    axes[1].scatter(
        east_c[repaired],
        north_c[repaired],
        s=6,
        c="#2ca02c",
        zorder=3,
        label=f"repaired fixes ({int(repaired.sum()) if totals is None else totals.repaired:,})",
    )
    if repaired.any():
        axes[1].legend(fontsize=8, loc="best", framealpha=0.85)
    fig.suptitle(f"track in local metres around {frame.lat0:.5f}, {frame.lon0:.5f}")
    return fig


def _channel_figure(bounds: ChannelBounds) -> Any:
    import matplotlib.pyplot as plt

    t = bounds.t - bounds.t[0]
    fig, axes = plt.subplots(2, 1, figsize=(13, 5.6), sharex=True, layout="constrained")
    keep = _decimate(t.size)
    for ax, name, x, lo, hi in (
        (axes[0], "east", bounds.east, bounds.east_lower, bounds.east_upper),
        (axes[1], "north", bounds.north, bounds.north_lower, bounds.north_upper),
    ):
        centre = 0.5 * (lo + hi)
        deviation = x - centre
        half = 0.5 * (hi - lo)
        ax.fill_between(
            t[keep], -half[keep], half[keep], color="#1f77b4", alpha=0.25, lw=0, label="REMA bounds"
        )
        ax.plot(t[keep], deviation[keep], color="#333333", lw=0.7, label="observed")
        f = bounds.flagged
        ax.scatter(
            t[f], deviation[f], s=10, c="#d62728", zorder=3, label=f"flagged ({int(f.sum()):,})"
        )
        ax.set_yscale("symlog", linthresh=10.0)
        ax.set_ylabel(f"{name} − prediction (m)")
        ax.grid(True, lw=0.3, alpha=0.5)
    axes[0].legend(fontsize=8, loc="upper right", ncols=3)
    axes[1].set_xlabel("seconds since segment start")
    fig.suptitle(
        f"track {_figure_text(bounds.track)}, segment {bounds.segment}: {t.size:,} points",
        parse_math=False,
    )
    return fig


#: Track ids longer than this are cut in figure titles (the HTML caption has them whole).
MAX_TITLE_ID_CHARS = 60


def _figure_text(track: str) -> str:
    """A track id for a figure title: shortened, on one line.

    The id is the user's text, so the title is drawn with ``parse_math=False``:
    matplotlib reads ``$...$`` as mathtext and raised on an id like
    ``$\\foo$`` (issue 18), losing the whole report.
    """
    text = " ".join(track.split())
    if len(text) > MAX_TITLE_ID_CHARS:
        text = text[: MAX_TITLE_ID_CHARS - 1] + "\u2026"
    return text


def _point_flags(prepared: Prepared, result: pd.DataFrame) -> NDArray[np.bool_]:
    """Per point: was any input row merged into it flagged (valid rows only)."""
    flags = np.zeros(len(prepared.points), bool)
    rows = np.flatnonzero((prepared.row_point >= 0) & (result["anomaly"].to_numpy() == 1))
    flags[prepared.row_point[rows]] = True
    return flags


def figures(inputs: ReportInputs) -> list[tuple[str, str, Any]]:
    """``(file stem, caption, matplotlib figure)`` for the track and the busiest segments."""
    import matplotlib

    matplotlib.use("Agg")  # no display needed, and no GUI toolkit imported
    fixes, result = inputs.fixes, inputs.result
    thinned = inputs.thinned
    if thinned is not None:
        # The channels need every fix of a segment: those read again for the busiest tracks.
        fixes, result = thinned.channel or (fixes.iloc[:0], result.iloc[:0])
    # The rows the detector used, exactly: nothing merged, nothing sorted.
    reason = result["invalid_reason"].to_numpy()
    usable = np.flatnonzero(reason == "")
    breaks = time_glitch_breaks(fixes, reason)[usable]  # the segments the detector drew
    prepared = grad_points(
        fixes.iloc[usable].reset_index(drop=True), inputs.params.max_gap_s, breaks
    )
    flags = _point_flags(prepared, result.iloc[usable].reset_index(drop=True))
    per_segment = pd.Series(flags).groupby(prepared.points["segment"].to_numpy()).sum()
    sizes = prepared.points.groupby("segment").size()
    ranked = sorted(per_segment.index, key=lambda s: (-int(per_segment[s]), -int(sizes[s]), s))
    chosen = ranked[:MAX_CHANNEL_SEGMENTS]
    out: list[tuple[str, str, Any]] = []
    # A thinned report draws its track from the sample, not from the channels' fixes.
    if (not inputs.fixes.empty) if thinned is not None else bool(len(prepared.points)):
        out.append(
            (
                "track",
                "Track as received (anomalies coloured by bias type, marker by "
                "time type) and recovered.",
                _track_figure(inputs),
            )
        )
    for bounds in rema_bounds(prepared, inputs.params, flags, chosen):
        out.append(
            (
                f"channels_segment{bounds.segment}",
                f"Track {bounds.track}, segment {bounds.segment}: distance from the REMA "
                "prediction per channel, REMA bounds, flagged fixes (symmetric log scale)."
                + (f" {thinned.channel_note}" if thinned is not None else ""),
                _channel_figure(bounds),
            )
        )
    return out


def _png(fig: Any, dpi: int = 100) -> bytes:
    import matplotlib.pyplot as plt

    buffer = io.BytesIO()
    with warnings.catch_warnings():
        # A track id in a script the font lacks (CJK, emoji) is drawn as boxes;
        # the HTML names it in full, so a warning per glyph is only noise.
        warnings.filterwarnings("ignore", "Glyph .* missing from font", UserWarning)
        fig.savefig(buffer, format="png", dpi=dpi)
    plt.close(fig)
    return buffer.getvalue()


def write_plots(inputs: ReportInputs, folder: str | Path) -> list[Path]:
    """The report's figures as PNG files in ``folder``; returns their paths."""
    out_dir = Path(folder)
    out_dir.mkdir(parents=True, exist_ok=True)
    paths = []
    for stem, _, fig in figures(inputs):
        path = out_dir / f"{stem}.png"
        _atomic_write(path, _png(fig, dpi=120))
        paths.append(path)
    return paths


def summary_rows(inputs: ReportInputs) -> list[tuple[str, str]]:
    """The summary table: what a reader asks first, as (label, value) text pairs."""
    result = inputs.result
    invalid = result["invalid_reason"].to_numpy() != ""
    anomaly = (result["anomaly"].to_numpy() == 1) & ~invalid
    thinned = inputs.thinned.totals if inputs.thinned is not None else None
    if thinned is None:
        totals = ResultCounts.of(result)
        tracks, usable, flagged = inputs.fixes["track"].nunique(), int((~invalid).sum()), None
        reasons = result.loc[invalid, "invalid_reason"].value_counts()
        by_type = {c: result.loc[anomaly, c].value_counts() for c in ("bias_type", "time_type")}
    else:
        totals = thinned.counts
        tracks, usable, flagged = len(thinned.tracks), thinned.usable, thinned.flagged
        reasons = thinned.reason_counts()
        by_type = {"bias_type": thinned.bias_counts(), "time_type": thinned.time_counts()}
    n = totals.rows
    rows = [
        ("input rows", f"{n:,}"),
        ("tracks", f"{tracks:,}"),
        ("usable fixes", f"{usable:,}"),
        (
            "anomalies (anomaly=1 in the CSV)",
            f"{totals.anomalies:,} ({100.0 * totals.anomalies / max(1, n):.1f} %): "
            f"{int(anomaly.sum()) if flagged is None else flagged:,} flagged by the detector, "
            f"{totals.invalid:,} invalid fixes",
        ),
    ]
    if len(reasons):
        rows.append(
            ("invalid fixes by reason", ", ".join(f"{k}: {int(v):,}" for k, v in reasons.items()))
        )
    if inputs.events is not None:
        rows.append(("fault events", f"{len(inputs.events):,}"))
    for column, label in (("bias_type", "by bias type"), ("time_type", "by time type")):
        counts = by_type[column]
        rows.append((label, ", ".join(f"{k}: {int(v):,}" for k, v in counts.items()) or "none"))
    rows.append(("alerts (permanent faults)", f"{totals.alerts:,}"))
    if math.isfinite(inputs.elapsed_s) and inputs.elapsed_s > 0:
        rows.append(
            (
                "throughput",
                f"{n / inputs.elapsed_s:,.0f} fixes/s "
                f"({1e6 * inputs.elapsed_s / max(1, n):.2f} µs per fix)",
            )
        )
    if inputs.model:
        rows.append(("model", inputs.model))
    rows.append(("anomaly threshold", f"{inputs.params.threshold:g}"))
    rows.extend(inputs.extra_summary.items())
    rows.extend(("warning", w) for w in inputs.warnings)
    return rows


_CSS = """
body{font-family:system-ui,-apple-system,Segoe UI,Roboto,sans-serif;margin:2em auto;max-width:1320px;
color:#222;padding:0 1em}
h1{font-size:1.6em;margin-bottom:.2em}h2{border-bottom:1px solid #ddd;padding-bottom:.2em;margin-top:1.6em}
table{border-collapse:collapse;font-size:.92em}td,th{padding:.25em .8em;border-bottom:1px solid #eee;
text-align:left}th{background:#f6f6f6}figure{margin:1em 0}img{max-width:100%;height:auto}
figcaption{color:#555;font-size:.9em}.muted{color:#777;font-size:.9em}
.track-svg{width:100%;height:560px;border:1px solid #ddd;background:#fcfcfc;cursor:grab}
#explorer button{min-width:2.2em}
"""


def _table(header: Sequence[str] | None, rows: Sequence[Sequence[str]], table_id: str = "") -> str:
    head = (
        ""
        if header is None
        else (
            "<thead><tr>" + "".join(f"<th>{html.escape(h)}</th>" for h in header) + "</tr></thead>"
        )
    )
    body = "".join(
        "<tr>"
        + "".join(f"<td>{c if isinstance(c, _Html) else html.escape(str(c))}</td>" for c in row)
        + "</tr>"
        for row in rows
    )
    attr = f" id='{html.escape(table_id)}'" if table_id else ""
    return f"<table{attr}>{head}<tbody>{body}</tbody></table>"


def _anomaly_rows(inputs: ReportInputs) -> tuple[list[str], list[list[str]], int]:
    result, fixes = inputs.result, inputs.fixes
    sel = np.flatnonzero(
        (result["anomaly"].to_numpy() == 1) & (result["invalid_reason"].to_numpy() == "")
    )
    numbers = inputs.thinned.rows if inputs.thinned is not None else None
    total = int(sel.size) if inputs.thinned is None else inputs.thinned.totals.flagged
    rows = []
    for i in sel[:MAX_TABLE_ROWS]:
        rows.append(
            [
                str(i if numbers is None else int(numbers[i])),
                str(fixes["track"].iloc[i]),
                _row_time(inputs, i),
                f"{fixes['lat'].iloc[i]:.6f}",
                f"{fixes['lon'].iloc[i]:.6f}",
                f"{result['score'].iloc[i]:.3f}",
                str(result["bias_type"].iloc[i]),
                str(result["time_type"].iloc[i]),
                f"{result['lat_clean'].iloc[i]:.6f}",
                f"{result['lon_clean'].iloc[i]:.6f}",
            ]
        )
    header = [
        "row",
        "track",
        "time",
        "lat",
        "lon",
        "score",
        "bias type",
        "time type",
        "lat clean",
        "lon clean",
    ]
    return header, rows, total


def _row_time(inputs: ReportInputs, i: int) -> str:
    """Row ``i``'s time as the output writes it (text inputs), else :func:`readable_time`."""
    if inputs.time_text is not None and str(inputs.time_text[i]):
        return str(inputs.time_text[i])
    return readable_time(float(inputs.fixes["t"].iloc[i]))


def readable_time(t: float) -> str:
    """Unix seconds as ``2026-11-23 12:00:05.2 UTC``; small numbers (relative clocks) as seconds."""
    if not math.isfinite(t):
        return ""
    if abs(t) < 1e8:  # not an epoch: seconds since some start
        return f"{t:,.1f} s"
    stamp = pd.Timestamp(t, unit="s", tz="UTC")
    return stamp.strftime("%Y-%m-%d %H:%M:%S") + f".{stamp.microsecond // 100_000} UTC"


#: Rows of the events table.
MAX_EVENT_ROWS = 500


class _Html(str):
    """Table cell text that is already HTML (not escaped again)."""


def _time_cell(t: float) -> str:
    """A ``<time>`` element: UTC text, rewritten in the viewer's local time by the page's script."""
    text = html.escape(readable_time(t))
    if not math.isfinite(t):
        return text
    return f"<time data-t='{t!r}'>{text}</time>"


def _event_rows(events: pd.DataFrame) -> tuple[list[str], list[list[str]]]:
    header = [
        "track",
        "start",
        "end",
        "duration (s)",
        "fixes",
        "bias type",
        "time type",
        "peak offset (m)",
        "peak score",
        "alert",
        "rows",
    ]
    records: list[dict[Any, Any]] = events.head(MAX_EVENT_ROWS).to_dict("records")
    rows = [
        [
            str(ev["track"]),
            _Html(_time_cell(float(ev["start"]))),
            _Html(_time_cell(float(ev["end"]))),
            f"{float(ev['duration_s']):,.1f}",
            f"{int(ev['fixes']):,}",
            str(ev["bias_type"]),
            str(ev["time_type"]),
            f"{float(ev['peak_offset_m']):,.1f}",
            f"{float(ev['peak_score']):.3f}",
            "yes" if int(ev["alert"]) else "",
            f"{int(ev['first_row'])}-{int(ev['last_row'])}",
        ]
        for ev in records
    ]
    return header, rows


def render_html(inputs: ReportInputs) -> str:
    """The whole report as one HTML string (see the module docstring)."""
    parts = [
        f"<!DOCTYPE html><html lang='en'><head><meta charset='utf-8'>"
        f"<title>{html.escape(inputs.title)}</title><style>{_CSS}</style></head><body>",
        f"<h1>{html.escape(inputs.title)}</h1>",
    ]
    if inputs.source:
        parts.append(f"<p class='muted'>input: {html.escape(inputs.source)}</p>")
    parts.append("<h2 id='summary'>Summary</h2>")
    parts.append(_table(None, summary_rows(inputs)))
    thinned = inputs.thinned
    if thinned is not None:
        parts.append(f"<p class='muted'>{html.escape(thinned_note(thinned))}</p>")
    doc = inputs.geojson
    if doc is None and thinned is not None:
        doc = geojson_document(
            inputs.fixes, inputs.result, inputs.events, rows=thinned.rows, parts=thinned.parts
        )
    elif doc is None:
        doc = geojson_document(inputs.fixes, inputs.result, inputs.events)
    block, note = embedded_geojson(doc, thinned=thinned is not None)
    parts.append(block)
    counts = None
    if thinned is not None:
        counts = {k: (v[0], v[1]) for k, v in thinned.totals.per_track.items()}
    explorer = track_explorer(inputs.fixes, inputs.result, note, counts=counts)
    if explorer:
        parts.append("<h2 id='explore'>Tracks, one at a time</h2>")
        parts.append(explorer)
    drawn = figures(inputs)
    for k, (stem, caption, fig) in enumerate(drawn):
        if k == 0:
            parts.append("<h2 id='track'>Track</h2>")
        if k == 1:
            parts.append(
                "<h2 id='channels'>Channels and REMA bounds</h2>"
                f"<p class='muted'>The {len(drawn) - 1} segment(s) with the most "
                "anomalies. The verdict is the network's; REMA bounds are one of its "
                "inputs, so a flagged fix may lie inside the band.</p>"
            )
        data = base64.b64encode(_png(fig)).decode("ascii")
        parts.append(
            f"<figure><img alt='{html.escape(stem)}' src='data:image/png;base64,{data}'>"
            f"<figcaption>{html.escape(caption)}</figcaption></figure>"
        )
    if inputs.events is not None:
        ev_header, ev_rows = _event_rows(inputs.events)
        parts.append("<h2 id='events'>Fault events</h2>")
        n_ev = len(inputs.events)
        shown_ev = (
            f"the first {len(ev_rows)} of {n_ev:,}" if n_ev > len(ev_rows) else f"all {n_ev:,}"
        )
        parts.append(
            f"<p class='muted'>{shown_ev} runs of consecutive flagged fixes per track "
            "(rows = input rows, from 0).</p>"
        )
        parts.append(_table(ev_header, ev_rows, table_id="events-table"))
    header, rows, total = _anomaly_rows(inputs)
    parts.append("<h2 id='anomalies'>Anomalies</h2>")
    shown = f"the first {len(rows)} of {total:,}" if total > len(rows) else f"all {total:,}"
    parts.append(f"<p class='muted'>{shown} anomalous fixes (row = input row, from 0).</p>")
    parts.append(_table(header, rows))
    parts.append(
        "<p class='muted'>Made by gradgps; no network access needed to view this "
        f"file.</p><script>{SCRIPT}</script></body></html>"
    )
    return "".join(parts)


def thinned_note(thinned: Thinned) -> str:
    """What a thinned report draws from (one sentence for the page)."""
    return (
        f"This run has {thinned.totals.counts.rows:,} rows: the counts and tables are exact; "
        "the track figure, the track view and the embedded GeoJSON are drawn from an "
        f"evenly spread sample of the usable fixes ({len(thinned.fixes):,} rows: at most "
        f"{TRACK_ROWS:,} per track and about {SAMPLE_ROWS:,} in all, plus flagged fixes), "
        "so memory stays bounded; gradgps detect --geojson writes every fix."
    )


def write_report(inputs: ReportInputs, path: str | Path) -> Path:
    """Write :func:`render_html` to ``path`` (folders created); returns the path."""
    out = Path(path)
    out.parent.mkdir(parents=True, exist_ok=True)
    _atomic_write(out, render_html(inputs).encode("utf-8"))
    return out


def _atomic_write(path: Path, data: bytes) -> None:
    """Write beside ``path`` and rename: a stopped run never leaves a half-written file."""
    partial = path.with_name(path.name + ".partial")
    try:
        partial.write_bytes(data)
        partial.replace(path)
    finally:
        partial.unlink(missing_ok=True)

"""``gradgps info FILE``: what a track file holds, before any detection.

Prints the number of tracks and points on one line a script can match
(``tracks: 28  points: 23,187``), the time span, then three narrow tables
(readable in 80 columns) per track and a total: rate, duration, gaps and
invalid rows; start and end; bounding box and speed. Then warnings (speeds
no road vehicle reaches, unusual rates, many unusable rows) and, for NMEA
logs, the rejected sentences. ``--json`` prints the same facts as JSON instead. The
definitions are those of :mod:`gradgps._tracks.summary`.
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import TYPE_CHECKING, Any

import click

from .options import column_map, column_options, option, read_options

if TYPE_CHECKING:
    from rich.console import Console

    from .._tracks.summary import Summary, TrackSummary

__all__ = ["info"]


@click.command()
@click.argument("path", metavar="FILE", type=click.Path(dir_okay=False, path_type=Path))
@column_options
@option("--json", "as_json", is_flag=True, help="print the summary as JSON")
def info(path: Path, fmt: str | None, as_json: bool, **kwargs: Any) -> None:
    """Summarise FILE: tracks, points, rate, gaps, extent, speeds, unusable rows."""
    import json

    from .._io.read import load_table
    from .._tracks.summary import summarize
    from .._tracks.track import to_fixes

    table = load_table(path, fmt, column_map(kwargs), read_options(kwargs))
    fixes = to_fixes(table)
    summary = summarize(fixes, rejected=table.rejected, notes=table.notes)
    if as_json:
        click.echo(json.dumps(summary.as_dict(), indent=2))
        return
    from rich.console import Console

    console = Console(highlight=False, markup=False)
    if not console.is_terminal:
        # Piped output has no terminal width: use $COLUMNS when set, else a wide page.
        width = int(os.environ.get("COLUMNS", "200") or 200)
        console = Console(highlight=False, markup=False, width=width)
    _print(console, summary)


def _duration(seconds: float | None) -> str:
    if seconds is None:
        return "-"
    if seconds < 60:
        return f"{seconds:.1f} s"
    whole = round(seconds)
    return f"{whole // 3600}:{whole % 3600 // 60:02d}:{whole % 60:02d}"


def _number(value: float | None, digits: int) -> str:
    return "-" if value is None else f"{value:.{digits}f}"


def _box(s: TrackSummary) -> tuple[str, str]:
    if s.lat_min is None or s.lat_max is None or s.lon_min is None or s.lon_max is None:
        return "-", "-"
    return f"{s.lat_min:.5f} .. {s.lat_max:.5f}", f"{s.lon_min:.5f} .. {s.lon_max:.5f}"


def _when(t: float | None) -> str:
    """Unix seconds as ``2026-11-23 10:00:05`` (UTC); small numbers (a relative clock) as seconds."""
    if t is None:
        return "-"
    if abs(t) < 1e8:
        return f"{t:,.1f} s"
    import datetime as dt

    return dt.datetime.fromtimestamp(t, dt.UTC).strftime("%Y-%m-%d %H:%M:%S")


def _print(console: Console, summary: Summary) -> None:
    """Three narrow tables (fit in 80 columns) rather than one wide one."""
    from rich.table import Table

    total = summary.total
    console.print(summary.source)
    console.print(f"tracks: {len(summary.tracks):,}  points: {total.points:,}")
    console.print(f"invalid rows: {total.invalid:,}", end="")
    if summary.invalid_reasons:
        reasons = "; ".join(f"{why}: {count:,}" for why, count in summary.invalid_reasons.items())
        console.print(f" ({reasons})", end="")
    console.print()
    console.print(f"time (UTC): {_when(total.start_s)} .. {_when(total.end_s)}")
    if summary.rejected:
        console.print(f"rejected sentences: {summary.rejected:,}")
    rows = [*summary.tracks, total]

    def table(headers: tuple[str, ...], right: set[str], cells: list[list[str]]) -> None:
        out = Table(show_footer=False, pad_edge=False)
        for header in headers:
            out.add_column(header, justify="right" if header in right else "left")
        for k, row in enumerate(cells):
            if k == len(cells) - 1:
                out.add_section()
            out.add_row(*row)
        console.print(out)

    table(
        ("track", "points", "invalid", "rate Hz", "duration", "gaps", "longest gap"),
        {"points", "invalid", "rate Hz", "duration", "gaps", "longest gap"},
        [
            [
                s.track,
                f"{s.points:,}",
                f"{s.invalid:,}",
                _number(s.rate_hz, 2),
                _duration(s.duration_s),
                f"{s.gaps:,}",
                _duration(s.longest_gap_s),
            ]
            for s in rows
        ],
    )
    table(
        ("track", "start (UTC)", "end (UTC)"),
        set(),
        [[s.track, _when(s.start_s), _when(s.end_s)] for s in rows],
    )
    table(
        ("track", "latitude", "longitude", "speed m/s med/p95/max"),
        set(),
        [
            [
                s.track,
                *_box(s),
                "-"
                if s.speed is None
                else f"{s.speed.median:.1f}/{s.speed.p95:.1f}/{s.speed.max:.1f} ({s.speed.source})",
            ]
            for s in rows
        ],
    )
    for note in summary.notes:
        console.print(f"note: {note}")
    for warning in summary.warnings:
        console.print(f"warning: {warning}")

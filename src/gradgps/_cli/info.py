"""``gradgps info FILE``: what a track file holds, before any detection.

Prints the number of tracks and points on one line a script can match
(``tracks: 28  points: 23,187``), then a table per track and a total: rate,
duration, gaps, bounding box, speed, invalid rows; and for NMEA logs the
rejected sentences. ``--json`` prints the same facts as JSON instead. The
definitions are those of :mod:`gradgps._tracks.summary`.
"""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING, Any

import click

from .options import column_map, column_options, option

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

    from .._io.read import read_table
    from .._tracks.summary import summarize
    from .._tracks.track import to_fixes

    table = read_table(path, fmt, column_map(kwargs))
    fixes = to_fixes(table)
    summary = summarize(fixes, rejected=table.rejected, notes=table.notes)
    if as_json:
        click.echo(json.dumps(summary.as_dict(), indent=2))
        return
    from rich.console import Console

    console = Console(highlight=False, markup=False)
    if not console.is_terminal:
        # Piped output has no width to fit; do not fold the table into 80 columns.
        console = Console(highlight=False, markup=False, width=200)
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


def _row(s: TrackSummary) -> list[str]:
    lat, lon = _box(s)
    speed = s.speed
    return [
        s.track,
        f"{s.points:,}",
        f"{s.invalid:,}",
        _number(s.rate_hz, 2),
        _duration(s.duration_s),
        f"{s.gaps:,}",
        _duration(s.longest_gap_s),
        lat,
        lon,
        "-" if speed is None else f"{speed.median:.1f} / {speed.p95:.1f} / {speed.max:.1f}",
        "-" if speed is None else speed.source,
    ]


def _print(console: Console, summary: Summary) -> None:
    from rich.table import Table

    total = summary.total
    console.print(summary.source)
    console.print(f"tracks: {len(summary.tracks):,}  points: {total.points:,}")
    console.print(f"invalid rows: {total.invalid:,}", end="")
    if summary.invalid_reasons:
        reasons = "; ".join(f"{why}: {count:,}" for why, count in summary.invalid_reasons.items())
        console.print(f" ({reasons})", end="")
    console.print()
    if summary.rejected:
        console.print(f"rejected sentences: {summary.rejected:,}")
    table = Table(show_footer=False)
    for header in (
        "track",
        "points",
        "invalid",
        "rate Hz",
        "duration",
        "gaps",
        "longest gap",
        "latitude",
        "longitude",
        "speed m/s median / p95 / max",
        "speed from",
    ):
        right = header in ("points", "invalid", "rate Hz", "duration", "gaps", "longest gap")
        table.add_column(header, justify="right" if right else "left")
    for track in summary.tracks:
        table.add_row(*_row(track))
    table.add_section()
    table.add_row(*_row(total))
    console.print(table)
    for note in summary.notes:
        console.print(f"note: {note}")
    for warning in summary.warnings:
        console.print(f"warning: {warning}")

"""Options shared by every command that reads tracks (format, column mapping, reader options)."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from typing import Any, TypeVar

import click

from .._tracks.track import SPEED_UNITS, ColumnMap, ReadOptions

__all__ = [
    "READER_FLAGS",
    "column_map",
    "column_options",
    "model_options",
    "option",
    "read_options",
]

F = TypeVar("F", bound=Callable[..., Any])

_ROLES = (
    ("time", "--time-col", "time column (seconds, ms/us epochs or ISO-8601)"),
    ("lat", "--lat-col", "latitude column, degrees"),
    ("lon", "--lon-col", "longitude column, degrees"),
    ("track", "--track-col", "track id column (one track per value)"),
    ("speed", "--speed-col", "speed column (its unit: --speed-unit)"),
    ("heading", "--heading-col", "heading/course column, degrees"),
    ("alt", "--alt-col", "altitude column, metres"),
    ("hdop", "--hdop-col", "HDOP column"),
    (
        "fix_quality",
        "--fix-col",
        "receiver fix quality column (GGA quality, RMC status A/V, GPX fix; 0, V or none = no fix)",
    ),
    ("satellites", "--sats-col", "satellites-in-use column (0 = no fix)"),
)


#: The reader options: (Python name, flag, click settings). ``None`` keeps today's guess,
#: so each help text says what that guess is.
_READER: tuple[tuple[str, str, dict[str, Any]], ...] = (
    (
        "decimal",
        "--decimal",
        {
            "type": click.Choice([".", ","]),
            "help": "decimal separator of numbers written as text (semicolon CSVs from "
            "European locales use ',')  [default: sniffed per column: ',' where the "
            "whole column uses decimal commas, else '.']",
        },
    ),
    (
        "time_format",
        "--time-format",
        {
            "metavar": "FMT",
            "help": "strptime format of the time column, e.g. '%d.%m.%Y %H:%M:%S' (with a "
            "separate date column: of 'DATE TIME')  [default: automatic: seconds, "
            "ms/us epochs, ISO-8601 or day-first dates]",
        },
    ),
    (
        "skip_rows",
        "--skip-rows",
        {
            "type": click.IntRange(min=0),
            "metavar": "N",
            "help": "lines to skip before the CSV header, e.g. 1 for GPSLogger's row-count "
            "line  [default: 0, or 1 when the first line is only a number]",
        },
    ),
    (
        "speed_unit",
        "--speed-unit",
        {
            "type": click.Choice(list(SPEED_UNITS)),
            "help": "unit of the speed column, converted to m/s on reading  [default: m/s, "
            "or the unit the column name says: speed_kmh, speed_mph, speed_knots]",
        },
    ),
    (
        "crs",
        "--crs",
        {
            "metavar": "CRS",
            "help": "coordinate reference system of projected X/Y (easting/northing) "
            "columns, e.g. EPSG:25832; converted to WGS84 longitude/latitude (needs "
            "gradgps[geo])  [default: degrees WGS84]",
        },
    ),
)
#: The reader flags, for commands that must refuse them (``detect --follow``).
READER_FLAGS = tuple(flag for _, flag, _ in _READER)


def column_options(func: F) -> F:
    """Add ``--format``, the ``--*-col`` options and the reader options to a command.

    In one place, so every command that reads track files reads them the same way.
    """
    for name, flag, settings in reversed(_READER):
        func = click.option(flag, name, default=None, **settings)(func)
    for role, flag, text in reversed(_ROLES):
        func = click.option(
            flag,
            f"{role}_col",
            default=None,
            metavar="NAME",
            help=f"{text}; auto-detected when omitted ('' = none)",
        )(func)
    func = click.option(
        "--format",
        "fmt",
        default=None,
        type=click.Choice(
            ["csv", "parquet", "gpx", "nmea", "geojson", "rosbag"], case_sensitive=False
        ),
        help="input format; by default from the content (first bytes), then the extension",
    )(func)
    return func


def column_map(kwargs: dict[str, Any]) -> ColumnMap:
    """Pop the ``--*-col`` values out of a command's kwargs into a ColumnMap."""
    return ColumnMap(**{role: kwargs.pop(f"{role}_col", None) for role, _, _ in _ROLES})


def read_options(kwargs: dict[str, Any]) -> ReadOptions:
    """Pop the reader options out of a command's kwargs; errors will name the CLI flags."""
    return ReadOptions(**{name: kwargs.pop(name, None) for name, _, _ in _READER}, cli=True)


def model_options(func: F) -> F:
    """Add ``--model`` (as ``model_dir``) and ``--threshold`` to a command that runs the detector."""
    func = click.option(
        "--threshold",
        type=float,
        default=None,
        help="anomaly threshold on the score, in (0, 1), and on the confirm head's read "
        "where the model has one  [default: the model's own; the shipped model's are in "
        "its config.json]",
    )(func)
    func = click.option(
        "--model",
        "model_dir",
        type=click.Path(file_okay=False, path_type=Path),
        default=None,
        help="model directory from 'gradgps train' (default: the shipped model)",
    )(func)
    return func


def option(
    *decls: str, path: str | None = None, minimum: float | None = None, **kwargs: Any
) -> Callable[[F], F]:
    """``click.option`` with the house conventions, written once for every command.

    ``path``: ``"file"`` or ``"dir"`` (``"existing file"``, ``"existing dir"``
    when it must exist) makes a :class:`pathlib.Path` option of that kind;
    ``minimum`` (an int or a float) a number option with that lower bound; a
    default other than ``None`` is shown in ``--help``.
    """
    if minimum is not None:
        kwargs["type"] = (
            click.IntRange(min=minimum)
            if isinstance(minimum, int)
            else click.FloatRange(min=minimum)
        )
    if path is not None:
        existing, _, kind = path.rpartition(" ")
        kwargs["type"] = click.Path(
            exists=bool(existing), dir_okay=kind == "dir", file_okay=kind == "file", path_type=Path
        )
    if kwargs.get("default") is not None and not kwargs.get("is_flag"):
        kwargs.setdefault("show_default", True)
    return click.option(*decls, **kwargs)

"""Options shared by every command that reads tracks (column mapping, format)."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from typing import Any, TypeVar

import click

from .._tracks.track import ColumnMap

__all__ = ["column_map", "column_options", "model_options", "option"]

F = TypeVar("F", bound=Callable[..., Any])

_ROLES = (
    ("time", "--time-col", "time column (seconds, ms/us epochs or ISO-8601)"),
    ("lat", "--lat-col", "latitude column, degrees"),
    ("lon", "--lon-col", "longitude column, degrees"),
    ("track", "--track-col", "track id column (one track per value)"),
    ("speed", "--speed-col", "speed column, m/s"),
    ("heading", "--heading-col", "heading/course column, degrees"),
    ("alt", "--alt-col", "altitude column, metres"),
    ("hdop", "--hdop-col", "HDOP column"),
)


def column_options(func: F) -> F:
    """Add ``--format`` and the ``--*-col`` options to a command."""
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


def model_options(func: F) -> F:
    """Add ``--model`` (as ``model_dir``) and ``--threshold`` to a command that runs the detector."""
    func = click.option(
        "--threshold",
        type=float,
        default=None,
        help="anomaly threshold on the score, in (0, 1)  [default: the model's own; "
        "the shipped model's is in its config.json]",
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

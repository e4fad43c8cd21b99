"""Errors on the command line: one clean ``error: ...`` line, never a traceback.

Every gradgps error already says what was wrong, where and what to do, so the
CLI prints its message as is. The group class below wraps every command, so
no command needs its own try/except. Exit codes: 2 for bad input or options
(:class:`InputError`, :class:`ConfigError`, like click's own usage errors),
1 for any other gradgps error (a model or dataset that cannot be loaded).
Anything else is a bug and keeps its traceback.
"""

from __future__ import annotations

import contextlib
from collections.abc import Iterator
from typing import IO, Any

import click

from .._exceptions import ConfigError, GradGPSError, InputError

__all__ = ["BadInputError", "CleanError", "ErrorReportingGroup", "click_errors"]


class CleanError(click.ClickException):
    """A gradgps error as click shows it: ``error: <message>`` on stderr, exit code 1."""

    def show(self, file: IO[Any] | None = None) -> None:
        click.echo(f"error: {self.format_message()}", file=file, err=file is None)


class BadInputError(CleanError):
    """Bad input data or options: exit code 2, like click's own usage errors."""

    exit_code = 2


#: Which extra installs a module an optional part of gradgps imports.
EXTRAS = {
    "torch": "train",
    "dask": "fleet",
    "distributed": "fleet",
    "redis": "fleet",
    "matplotlib": "report",
    "onnx": "onnx",
    "onnxruntime": "onnx",
    "rosbags": "ros",
    "pyarrow": "io",
    "geopandas": "geo",
    "movingpandas": "geo",
    "shapely": "geo",
    "pyproj": "geo",
}


def missing_extra(exc: ModuleNotFoundError, command: str | None) -> str | None:
    """One line naming the extra to install, for a module of an extra; else ``None``."""
    top = (exc.name or "").split(".")[0]
    extra = EXTRAS.get(top)
    if extra is None:
        return None
    what = f"'gradgps {command}'" if command else "this command"
    return f"{what} needs {top}, which is not installed: pip install 'gradgps[{extra}]'"


@contextlib.contextmanager
def click_errors() -> Iterator[None]:
    """A gradgps error raised inside becomes click's plain ``Error: <message>`` (exit code 1).

    How ``bench``, ``inject``, ``tune-rema`` and the peers suite report a
    failed run, from before :class:`ErrorReportingGroup` did it for every
    command; one spelling of it, so their messages and exit codes stay as
    they were.
    """
    try:
        yield
    except GradGPSError as exc:
        raise click.ClickException(str(exc)) from exc


class ErrorReportingGroup(click.Group):
    """A click group that turns gradgps errors raised by its commands into :class:`CleanError`,
    and a missing optional dependency into one line naming the extra to install."""

    def invoke(self, ctx: click.Context) -> Any:
        try:
            return super().invoke(ctx)
        except (InputError, ConfigError) as exc:
            raise BadInputError(str(exc)) from exc
        except GradGPSError as exc:
            raise CleanError(str(exc)) from exc
        except ModuleNotFoundError as exc:
            line = missing_extra(exc, ctx.invoked_subcommand)
            if line is None:
                raise
            raise CleanError(line) from exc

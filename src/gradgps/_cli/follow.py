"""``gradgps detect --follow``: the I/O around :func:`gradgps._run.follow.follow_lines`.

Kept apart from ``detect.py`` because it shares nothing with the batch path
but the options: it reads line by line, writes line by line and flushes after
every line, so a reader at the other end of a pipe sees each verdict at once.
"""

from __future__ import annotations

import sys
from pathlib import Path

import click

from .._tracks.track import ColumnMap

__all__ = ["run_follow"]


def run_follow(
    input_path: Path,
    output: Path | None,
    model_dir: Path | None,
    threshold: float | None,
    fmt: str | None,
    columns: ColumnMap,
) -> None:
    """Follow INPUT ('-' = standard input) and write one CSV line per input line to OUTPUT/stdout."""
    from .._run.follow import follow_lines

    with click.open_file(str(input_path), "r", encoding="utf-8", errors="replace") as source:
        if output is None:

            def write(text: str) -> None:
                click.echo(text)  # click.echo flushes

            counts = follow_lines(
                source, write, model=model_dir, threshold=threshold, columns=columns, fmt=fmt
            )
        else:
            with output.open("w", encoding="utf-8", newline="") as sink:

                def write_file(text: str) -> None:
                    sink.write(text + "\n")
                    sink.flush()

                counts = follow_lines(
                    source,
                    write_file,
                    model=model_dir,
                    threshold=threshold,
                    columns=columns,
                    fmt=fmt,
                )
    click.echo(
        f"followed {counts.lines:,} lines: {counts.fixes:,} fixes scored, "
        f"{counts.anomalies:,} anomalies, {counts.invalid:,} unusable lines",
        err=True,
    )
    sys.stderr.flush()

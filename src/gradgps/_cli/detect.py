"""``gradgps detect INPUT -o OUT``: flag, classify and repair every fix of a track file.

The output has one row per input row, in input order, with every input
column kept, plus the detector's columns: ``anomaly`` (0/1), ``score``
(0..1), ``bias_type``, ``time_type``, ``lat_clean``, ``lon_clean``,
``alert`` (0/1) and ``invalid_reason`` (empty for a usable fix).

CSV input is processed ``--chunk-size`` rows at a time in bounded memory
(:mod:`gradgps._run.chunked`), with streaming semantics: rows in file order, one
streaming detector per track, so a fix whose time is not after the previous
fix of its track is flagged invalid. ``--chunk-size 0`` and the other
formats read the whole file and run batch detection, which sorts each track
by time and merges repeated timestamps first. For time-ordered tracks
without repeated timestamps both give the same numbers.

Where the input is outside what the model was validated on (sampling
slower or faster than its ``validated`` rates, repeated timestamps,
implausible speeds, irregular sampling; :mod:`gradgps._tracks.input_checks`),
one ``warning: ...`` line per problem goes to standard error, and into the
report's summary with ``--report``.
"""

from __future__ import annotations

import sys
from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

import click

from .options import column_map, column_options, model_options, option

if TYPE_CHECKING:
    from .._tracks.track import ColumnMap

__all__ = ["detect"]


@click.command()
@click.argument(
    "input_path", metavar="INPUT", type=click.Path(exists=True, allow_dash=True, path_type=Path)
)
@option(
    "-o",
    "--output",
    path="file",
    help="output file: .csv, .csv.gz or .parquet (with --follow: CSV lines, "
    "default standard output)",
)
@model_options
@option(
    "--follow",
    is_flag=True,
    help="live mode: read INPUT ('-' = standard input) line by line as it arrives "
    "(CSV with a header, or NMEA) and print one result line per line at once",
)
@option(
    "--report",
    "report_path",
    path="file",
    help="also write a self-contained HTML report (track, bounds, summary)",
)
@option(
    "--plots",
    "plots_dir",
    path="dir",
    help="also write the report's figures as PNG files into this folder",
)
@option(
    "--chunk-size",
    minimum=0,
    default=200_000,
    help="CSV rows per chunk (bounded memory, file order per track); "
    "0 = whole file, batch (sorts each track by time); --report/--plots read "
    "the whole file",
)
@column_options
def detect(
    input_path: Path,
    output: Path | None,
    model_dir: Path | None,
    threshold: float | None,
    follow: bool,
    report_path: Path | None,
    plots_dir: Path | None,
    chunk_size: int,
    fmt: str | None,
    **cols: Any,
) -> None:
    """Detect, classify and repair faults in every fix of INPUT; write OUTPUT.

    CSV input is processed in chunks of --chunk-size rows with one streaming
    detector per track, in file order (memory stays bounded however large
    the file); other formats, --chunk-size 0 and --report/--plots process
    the whole file at once, sorting each track by time. With --follow, INPUT
    is read as a live stream (e.g. 'tail -f log.nmea | gradgps detect
    --follow -') and results go to standard output.
    """
    if follow:
        if report_path is not None or plots_dir is not None:
            raise click.UsageError("--report and --plots need a whole file, not --follow")
        _run_follow(input_path, output, model_dir, threshold, fmt, column_map(cols))
        return
    if output is None:
        raise click.UsageError("missing option '-o' / '--output'")
    if str(input_path) == "-":
        raise click.UsageError("reading standard input ('-') needs --follow")
    import time

    import pandas as pd

    from .._grad.detector import Detector
    from .._io.read import read_table, resolve_format, write_table
    from .._tracks.input_checks import input_warnings, validated_rates
    from .._tracks.track import to_fixes

    whole_file = report_path is not None or plots_dir is not None
    if chunk_size > 0 and not whole_file and resolve_format(input_path, fmt) == "csv":
        _detect_in_chunks(input_path, output, model_dir, threshold, chunk_size, column_map(cols))
        return
    table = read_table(input_path, fmt, column_map(cols))
    fixes = to_fixes(table)
    detector = Detector(model_dir, threshold=threshold)
    lowest, highest = validated_rates(detector.model_.config)
    warnings = input_warnings(fixes, min_rate_hz=lowest, max_rate_hz=highest)
    started = time.perf_counter()
    result = detector.detect(fixes)
    elapsed = time.perf_counter() - started
    frame = table.frame.reset_index(drop=True)
    clash = [c for c in result.columns if c in frame.columns]
    if clash:
        raise click.UsageError(f"{input_path} already has columns {clash}; rename them first")
    out = pd.concat([frame, result.reset_index(drop=True)], axis=1)
    write_table(out, output)
    n = len(out)
    flagged = int(result["anomaly"].sum())
    invalid = int((result["invalid_reason"] != "").sum())
    alerts = int(result["alert"].sum())
    rate = n / elapsed if elapsed > 0 else float("inf")
    click.echo(
        f"wrote {output}: {n:,} rows, {flagged:,} anomalies ({invalid:,} invalid fixes), "
        f"{alerts:,} alerts; {rate:,.0f} fixes/s"
    )
    _warn(warnings)
    from .report import write_report_outputs

    write_report_outputs(
        report_path,
        plots_dir,
        fixes,
        result,
        detector,
        elapsed,
        str(input_path),
        warnings=warnings,
    )


def _warn(warnings: Sequence[str]) -> None:
    """Say once, on standard error, where the input is outside what the model was validated on."""
    for warning in warnings:
        click.echo(f"warning: {warning}", err=True)


def _detect_in_chunks(
    input_path: Path,
    output: Path,
    model_dir: Path | None,
    threshold: float | None,
    chunk_size: int,
    columns: ColumnMap,
) -> None:
    from rich.console import Console
    from rich.progress import (
        BarColumn,
        MofNCompleteColumn,
        Progress,
        TextColumn,
        TimeElapsedColumn,
        TimeRemainingColumn,
    )

    from .._run.chunked import detect_csv_in_chunks

    progress = Progress(
        TextColumn("detect"),
        BarColumn(),
        MofNCompleteColumn(),
        TextColumn("rows, {task.fields[rate]} rows/s"),
        TimeElapsedColumn(),
        TimeRemainingColumn(),
        console=Console(stderr=True),
    )
    task = progress.add_task("detect", total=None, rate="-")

    def advance(rows: int) -> None:
        progress.advance(task, rows)
        elapsed = progress.tasks[0].elapsed or 0.0
        done = progress.tasks[0].completed
        progress.update(task, rate=f"{done / elapsed:,.0f}" if elapsed > 0 else "-")

    with progress:
        summary = detect_csv_in_chunks(
            input_path,
            output,
            columns=columns,
            model=model_dir,
            threshold=threshold,
            chunk_size=chunk_size,
            on_start=lambda total: progress.update(task, total=total),
            on_chunk=advance,
        )
    click.echo(
        f"wrote {output}: {summary.rows:,} rows, {summary.anomalies:,} anomalies "
        f"({summary.invalid:,} invalid fixes), {summary.alerts:,} alerts; "
        f"{summary.rows_per_second:,.0f} fixes/s"
    )
    _warn(summary.warnings)


def _run_follow(
    input_path: Path,
    output: Path | None,
    model_dir: Path | None,
    threshold: float | None,
    fmt: str | None,
    columns: ColumnMap,
) -> None:
    """``--follow``: follow INPUT ('-' = standard input) and write one CSV line per input line to OUTPUT/stdout."""
    from .._run.follow import follow_lines

    with click.open_file(str(input_path), "r", encoding="utf-8", errors="replace") as source:
        # Line by line, flushing after every line, so a reader at the other end
        # of a pipe sees each verdict at once.
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

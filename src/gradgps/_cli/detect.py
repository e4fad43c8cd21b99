"""``gradgps detect INPUT -o OUT``: flag, classify and repair every fix of a track file.

The output has one row per input row, in input order, with every input
column kept, plus the detector's columns: ``anomaly`` (0/1), ``score``
(0..1), ``bias_type``, ``time_type``, ``lat_clean``, ``lon_clean``,
``alert`` (0/1) and ``invalid_reason`` (empty for a usable fix).

Input of every format (CSV, Parquet and GeoParquet, GPX, NMEA, GeoJSON, ROS bags) is
processed ``--chunk-size`` rows at a time in bounded memory (:mod:`gradgps._run.chunked`;
Parquet by record batches of one row group at a time; GPX, NMEA, GeoJSON and ROS bags in
two streaming passes, :func:`gradgps._io.read.table_chunks`), and ``--geojson``
and ``--gpx`` are written as results come
(:class:`gradgps._io.export_streamed.StreamedExports`). ``--chunk-size 0`` asks for
the largest chunks the memory bound allows (:func:`gradgps._io.read.chunk_rows`), not
for the whole file: no mode of this command holds the file, since the chunks' outputs
are byte for byte those of whole-file detection (issue 18). Every mode reads each
track in row order with one rule (see
:func:`gradgps._tracks.preprocess.stream_reasons`): a fix whose time is not
after the previous usable fix of its track is flagged invalid, never merged,
so every mode, ``--report`` included, gives the same rows flagged and the
same clean positions.
"""

from __future__ import annotations

import contextlib
import sys
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import TYPE_CHECKING, Any

import click

from .options import READER_FLAGS, column_map, column_options, model_options, option, read_options

if TYPE_CHECKING:
    from .._run.settings import RunSettings

__all__ = ["detect"]


@click.command()
@click.argument(
    "input_path", metavar="INPUT", type=click.Path(exists=True, allow_dash=True, path_type=Path)
)
@option(
    "-o",
    "--output",
    path="file",
    help="output table: .csv, .csv.gz or .parquet (with --follow: CSV lines, "
    "default standard output); optional when --report, --plots, --events, "
    "--geojson or --gpx is given",
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
    help="also write a self-contained HTML report (track, bounds, summary, events)",
)
@option(
    "--plots",
    "plots_dir",
    path="dir",
    help="also write the report's figures as PNG files into this folder",
)
@option(
    "--events",
    "events_path",
    path="file",
    help="also write the fault events (track, start, end, duration, bias type, "
    "time type, peak offset, alert) as a table (.csv, .csv.gz, .parquet)",
)
@option(
    "--geojson",
    "geojson_path",
    path="file",
    help="also write GeoJSON: flagged fixes with their verdicts, the repaired "
    "track as lines, the events",
)
@option("--gpx", "gpx_path", path="file", help="also write the repaired track as GPX")
@option(
    "--chunk-size",
    minimum=0,
    default=200_000,
    help="rows per chunk of the input, any format (bounded memory: at "
    "most 500,000 rows and 4,000,000 cells, whatever is asked); 0 = the largest chunks "
    "that bound allows. Same results at any size",
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
    events_path: Path | None,
    geojson_path: Path | None,
    gpx_path: Path | None,
    chunk_size: int,
    fmt: str | None,
    **cols: Any,
) -> None:
    """Detect, classify and repair faults in every fix of INPUT; write OUTPUT.

    Every mode gives the same answer: each track is read in row order, and a
    fix whose time is not after the previous usable fix of its track (a
    repeated or backward timestamp) is flagged invalid, never merged. Input of
    any format is processed in chunks of --chunk-size rows
    (memory stays bounded however large the file, --report, --geojson and
    --gpx included; 0 asks for the largest chunks, never the whole file). With
    --follow, INPUT is read as a live stream (e.g. 'tail
    -f log.nmea | gradgps detect --follow -') and results go to standard
    output.
    """
    extras = (report_path, plots_dir, events_path, geojson_path, gpx_path)
    reading = read_options(cols)
    from .._run.settings import RunSettings

    settings = RunSettings(model_dir, threshold, fmt, column_map(cols), reading)
    if follow:
        if reading.given:
            # A live stream is parsed value by value, with no column to sniff or convert.
            raise click.UsageError(f"{', '.join(READER_FLAGS)} read files, not --follow")
        if any(p is not None for p in extras):
            raise click.UsageError(
                "--report, --plots, --events, --geojson and --gpx need a whole file, not --follow"
            )
        _run_follow(input_path, output, settings)
        return
    if output is None and all(p is None for p in extras):
        raise click.UsageError(
            "name an output: -o/--output, --report, --plots, --events, --geojson or --gpx"
        )
    if str(input_path) == "-":
        raise click.UsageError("reading standard input ('-') needs --follow")
    if report_path is not None or plots_dir is not None:
        _need_matplotlib()
    import pandas as pd

    from .._grad.detector import Detector
    from .._grad.events import EventBuilder
    from .._io.export_streamed import StreamedExports
    from .._io.read import chunk_rows, write_table
    from .._io.times import output_time_text
    from .._result import ResultCounts
    from .._run.report_data import ReportCollector
    from .._tracks.track import to_fixes

    drawing = report_path is not None or plots_dir is not None
    exports = geojson_path is not None or gpx_path is not None
    chunk_size = chunk_rows(chunk_size)
    # Every format is read in chunks; the report and plots draw from a collection of
    # bounded size (report_data), --geojson/--gpx are written as results come.
    collector = ReportCollector() if drawing else None
    exporter = StreamedExports(geojson_path, gpx_path) if exports else None
    events = EventBuilder() if (events_path or report_path or geojson_path) else None
    detector = Detector(model_dir, threshold=threshold)
    time_column: Any = None

    def collect(fixes: pd.DataFrame, result: pd.DataFrame, frame: pd.DataFrame) -> None:
        nonlocal time_column
        if time_column is None:  # the first chunk's rows say how the input writes time
            time_column = _time_column(frame, fixes)
        if events is not None:
            events.add(fixes, result)
        if exporter is not None:
            exporter.add(fixes, result)
        if collector is not None:
            collector.add(fixes, result, output_time_text(frame, _time_name(fixes)))

    summary = _detect_in_chunks(input_path, output, settings, chunk_size, collect)
    counts = ResultCounts(summary.rows, summary.anomalies, summary.invalid, summary.alerts)
    warnings: list[str] = list(summary.warnings)
    elapsed = summary.seconds
    rate = summary.rows_per_second
    what = str(output) if output is not None else str(input_path)
    click.echo(
        f"{'wrote ' if output is not None else ''}{what}: {counts.text()}; {rate:,.0f} fixes/s"
    )
    for warning in warnings:
        # Once, on standard error: the input is outside what the model was validated on.
        click.echo(f"warning: {warning}", err=True)
    if events is None and collector is None and exporter is None:
        return
    table_events = events.events() if events is not None else None
    if events_path is not None and table_events is not None:
        write_table(_events_in_input_form(table_events, time_column), events_path)
        click.echo(f"events: {events_path} ({len(table_events):,} fault events)")
    if exporter is not None:
        with exporter, _steps() as step:
            step("write " + " and ".join(str(p) for p in (geojson_path, gpx_path) if p))
            exporter.finish(table_events)
        if geojson_path is not None:
            click.echo(f"geojson: {geojson_path}")
        if gpx_path is not None:
            click.echo(f"gpx: {gpx_path} (the repaired track)")
    if collector is not None:
        from .report import write_report_outputs

        thinned = None
        drawn: Any = None
        if collector.rows == 0:  # no chunk at all (an empty Parquet file): an empty report
            from .._run.chunked import no_fixes

            drawn = (no_fixes(), detector.detect_fixes(no_fixes()), None)
        elif (drawn := collector.whole()) is None:

            def reread() -> Iterator[pd.DataFrame]:
                from .._io.read import table_chunks

                for table in table_chunks(
                    input_path, chunk_size, settings.columns, settings.options, settings.fmt
                ):
                    yield to_fixes(table)

            with _steps() as step:
                step("collect the busiest tracks again for the report")
                thinned = collector.thinned(reread)
            if thinned is not None:
                drawn = (thinned.fixes, thinned.result, thinned.time_text)
        if drawn is not None and drawn[0] is not None:
            with _steps() as step:
                step("draw the report")
                write_report_outputs(
                    report_path,
                    plots_dir,
                    drawn[0],
                    drawn[1],
                    detector,
                    elapsed,
                    str(input_path),
                    events=table_events,
                    warnings=warnings,
                    time_text=drawn[2],
                    thinned=thinned,
                )


@contextlib.contextmanager
def _steps() -> Iterator[Callable[[str], None]]:
    """A spinner with the current step and the elapsed time on stderr (the steps after
    detection: exports and the report)."""
    from rich.console import Console
    from rich.progress import Progress, SpinnerColumn, TextColumn, TimeElapsedColumn

    progress = Progress(
        SpinnerColumn(),
        TextColumn("{task.description}"),
        TimeElapsedColumn(),
        console=Console(stderr=True),
        transient=True,
    )
    task = progress.add_task("start", total=None)
    with progress:
        yield lambda text: progress.update(task, description=text)


def _need_matplotlib() -> None:
    try:
        import matplotlib  # noqa: F401
    except ImportError:
        raise click.ClickException(
            "--report and --plots need matplotlib: pip install 'gradgps[report]'"
        ) from None


def _time_name(fixes: Any) -> str | None:
    cmap = fixes.attrs.get("columns")
    return None if cmap is None else cmap.time


def _time_column(frame: Any, fixes: Any) -> Any:
    cmap = fixes.attrs.get("columns")
    if cmap is None or cmap.time is None or cmap.time not in frame.columns:
        return None
    return frame[cmap.time]


def _events_in_input_form(events: Any, time_column: Any) -> Any:
    """Event start/end as the input wrote its times: ISO-8601 text for text or datetime times."""
    import pandas as pd

    if time_column is None:
        return events
    if pd.api.types.is_numeric_dtype(time_column.dtype):
        return events
    from .._io.times import iso_utc

    out = events.copy()
    for c in ("start", "end"):
        out[c] = iso_utc(out[c].to_numpy(float))
    return out


def _detect_in_chunks(
    input_path: Path,
    output: Path | None,
    settings: RunSettings,
    chunk_size: int,
    on_result: Any = None,
) -> Any:
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

    def start(total: int) -> None:
        # Shown once the file's structure is checked: a file refused before (a damaged
        # bag, a CSV without a header) gets its one error line and no empty bar.
        progress.update(task, total=total)
        progress.start()

    try:
        return detect_csv_in_chunks(
            input_path,
            output,
            settings=settings,
            chunk_size=chunk_size,
            on_start=start,
            on_chunk=advance,
            on_result=on_result,
        )
    finally:
        progress.stop()


def _run_follow(input_path: Path, output: Path | None, settings: RunSettings) -> None:
    """``--follow``: follow INPUT ('-' = standard input) and write one CSV line per input line to OUTPUT/stdout."""
    from .._grad.detector import load_grad_model
    from .._run.follow import HOLD_LINES, follow_lines

    def warn(message: str) -> None:
        # At once, before the first result line: a live reader sees why lines were dropped.
        click.echo(f"warning: {message}", err=True)

    model = load_grad_model(settings.model)
    if model.params.settles(model.dims):  # else a live reader may think the first line lost
        click.echo(
            "note: this model settles each verdict with the next fix of its track: "
            "a fix's line is written when that fix arrives (or at the end of the input)",
            err=True,
        )

    with contextlib.ExitStack() as stack:
        source = stack.enter_context(
            click.open_file(str(input_path), "r", encoding="utf-8", errors="replace")
        )
        # Line by line, flushing after every line, so a reader at the other end
        # of a pipe sees each verdict at once.
        sink = (
            None
            if output is None
            else stack.enter_context(output.open("w", encoding="utf-8", newline=""))
        )

        def write(text: str) -> None:
            if sink is None:
                click.echo(text)  # click.echo flushes
            else:
                sink.write(text + "\n")
                sink.flush()

        counts = follow_lines(
            source,
            write,
            model=settings.model,
            threshold=settings.threshold,
            columns=settings.columns,
            fmt=settings.fmt,
            warn=warn,
        )
    click.echo(
        f"followed {counts.lines:,} lines: {counts.fixes:,} fixes scored, "
        f"{counts.anomalies:,} anomalies, {counts.invalid:,} unusable lines",
        err=True,
    )
    if counts.unsettled:
        click.echo(
            f"warning: {counts.unsettled:,} fixes went out with their verdict at once: "
            f"more than {HOLD_LINES:,} lines waited behind them for their track's next fix "
            "(one stream per track keeps each verdict one fix late)",
            err=True,
        )
    sys.stderr.flush()

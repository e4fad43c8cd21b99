"""``gradgps detect-fleet INPUT_DIR -o OUTPUT_DIR``: a whole fleet's logs on a Dask cluster.

INPUT_DIR holds one file per vehicle (``<id>.parquet``/``.csv``) or a
hive-partitioned dataset (``vehicle=<id>/part-*.parquet``); OUTPUT_DIR gets
the same layout, each file with its input rows plus the detector's columns
(what ``gradgps detect`` writes for it). One Dask task per vehicle, no
shuffle; see :mod:`gradgps._run.fleet_dask` and docs/fleet.md.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import click

from .options import column_map, column_options, model_options, option, read_options

__all__ = ["MAX_WARNINGS_SHOWN", "detect_fleet"]

#: Input warnings printed at the end of a run at most (a fleet may have thousands).
MAX_WARNINGS_SHOWN = 20


@click.command("detect-fleet")
@click.argument("input_dir", type=click.Path(exists=True, file_okay=False, path_type=Path))
@option(
    "-o",
    "--output",
    "output_dir",
    path="dir",
    required=True,
    help="output directory (new or empty); same layout as INPUT_DIR",
)
@option(
    "--scheduler",
    metavar="ADDRESS",
    help="Dask scheduler to run on, e.g. tcp://10.0.0.5:8786 (workers need gradgps "
    "and the files); default: a local cluster",
)
@option(
    "--workers",
    minimum=1,
    help="local cluster size in single-thread worker processes (default: one per CPU)",
)
@option(
    "--chunk-size",
    minimum=0,
    default=200_000,
    help="rows per chunk: each vehicle's files are read one after the other, this many "
    "rows at a time (a worker's memory is one chunk, whatever the vehicle's size; at most "
    "500,000 rows and 4,000,000 cells); 0 = the largest chunks, as for detect",
)
@model_options
@column_options
def detect_fleet(
    input_dir: Path,
    output_dir: Path,
    scheduler: str | None,
    workers: int | None,
    chunk_size: int,
    model_dir: Path | None,
    threshold: float | None,
    fmt: str | None,
    **cols: Any,
) -> None:
    """Detect faults in every vehicle of INPUT_DIR on a Dask cluster; write OUTPUT_DIR."""
    from rich.progress import (
        BarColumn,
        MofNCompleteColumn,
        Progress,
        TextColumn,
        TimeRemainingColumn,
    )

    from .._grad.detector import load_grad_model
    from .._io.read import chunk_rows
    from .._run.chunked import detect_partition
    from .._run.fleet_dask import dask_client
    from .._run.fleet_dask import detect_fleet as run_on_cluster
    from .._run.settings import RunSettings

    settings = RunSettings(model_dir, threshold, fmt, column_map(cols), read_options(cols))
    load_grad_model(model_dir)  # a bad model fails here, not in a thousand tasks
    with (
        dask_client(scheduler, workers) as client,
        Progress(
            TextColumn("detecting vehicles"),
            BarColumn(),
            MofNCompleteColumn(),
            TimeRemainingColumn(),
            transient=True,
        ) as progress,
    ):
        task = progress.add_task("vehicles", total=None)
        summary = run_on_cluster(
            input_dir,
            output_dir,
            client,
            task=detect_partition,
            settings=settings,
            chunk_size=chunk_rows(chunk_size),
            on_start=lambda n: progress.update(task, total=n),
            on_partition=lambda _: progress.advance(task),
        )
    rate = summary.rows / summary.seconds if summary.seconds > 0 else float("inf")
    click.echo(
        f"wrote {output_dir}: {summary.vehicles:,} vehicles, {summary.rows:,} rows, "
        f"{summary.anomalies:,} anomalies ({summary.invalid:,} invalid fixes), "
        f"{summary.alerts:,} alerts; {rate:,.0f} fixes/s"
    )
    # On standard error, as `detect` says them: each file outside what the model was
    # validated on, by its path under INPUT_DIR; a long list is cut, with its length.
    shown = summary.warnings[:MAX_WARNINGS_SHOWN]
    for warning in shown:
        click.echo(f"warning: {warning}", err=True)
    if len(summary.warnings) > len(shown):
        click.echo(
            f"warning: ... and {len(summary.warnings) - len(shown):,} more input warnings "
            "(run `gradgps detect` on a file to see its own)",
            err=True,
        )

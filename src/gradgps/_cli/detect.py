"""``gradgps detect INPUT -o OUT``: flag, classify and repair every fix of a track file.

The output has one row per input row, in input order, with every input
column kept, plus the detector's columns: ``anomaly`` (0/1), ``score``
(0..1), ``bias_type``, ``time_type``, ``lat_clean``, ``lon_clean``,
``alert`` (0/1) and ``invalid_reason`` (empty for a usable fix).
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import click

from .options import column_map, column_options

__all__ = ["detect"]


@click.command()
@click.argument("input_path", metavar="INPUT",
                type=click.Path(exists=True, allow_dash=True, path_type=Path))
@click.option("-o", "--output", type=click.Path(dir_okay=False, path_type=Path), default=None,
              help="output file: .csv, .csv.gz or .parquet (with --follow: CSV lines, "
                   "default standard output)")
@click.option("--model", "model_dir", type=click.Path(file_okay=False, path_type=Path),
              default=None, help="model directory from 'gradgps train' (default: the shipped model)")
@click.option("--threshold", type=float, default=None,
              help="anomaly threshold on the score, overriding the model's")
@click.option("--follow", is_flag=True,
              help="live mode: read INPUT ('-' = standard input) line by line as it arrives "
                   "(CSV with a header, or NMEA) and print one result line per line at once")
@click.option("--report", "report_path", type=click.Path(dir_okay=False, path_type=Path),
              default=None, help="also write a self-contained HTML report (track, bounds, summary)")
@click.option("--plots", "plots_dir", type=click.Path(file_okay=False, path_type=Path),
              default=None, help="also write the report's figures as PNG files into this folder")
@column_options
def detect(input_path: Path, output: Path | None, model_dir: Path | None, threshold: float | None,
           follow: bool, report_path: Path | None, plots_dir: Path | None,
           fmt: str | None, **cols: Any) -> None:
    """Detect, classify and repair faults in every fix of INPUT; write OUTPUT.

    With --follow, INPUT is read as a live stream (e.g. 'tail -f log.nmea |
    gradgps detect --follow -') and results go to standard output.
    """
    if follow:
        if report_path is not None or plots_dir is not None:
            raise click.UsageError("--report and --plots need a whole file, not --follow")
        from .follow import run_follow

        run_follow(input_path, output, model_dir, threshold, fmt, column_map(cols))
        return
    if output is None:
        raise click.UsageError("missing option '-o' / '--output'")
    if str(input_path) == "-":
        raise click.UsageError("reading standard input ('-') needs --follow")
    import time

    import pandas as pd

    from .._detector import Detector
    from .._io import read_table, write_table
    from .._track import to_fixes

    table = read_table(input_path, fmt, column_map(cols))
    fixes = to_fixes(table)
    detector = Detector(model_dir, threshold=threshold)
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
    click.echo(f"wrote {output}: {n:,} rows, {flagged:,} anomalies ({invalid:,} invalid fixes), "
               f"{alerts:,} alerts; {rate:,.0f} fixes/s")
    from .report import write_report_outputs

    write_report_outputs(report_path, plots_dir, fixes, result, detector, elapsed, str(input_path))

"""``gradgps inject``: corrupt a clean track with a benchmark protocol and write the labels."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import click

from .._tracks.track import ColumnMap, ReadOptions, Table
from .errors import click_errors
from .options import column_map, column_options, option, read_options

__all__ = ["inject"]


def _read_input(path: Path, fmt: str | None, reading: ReadOptions) -> Table:
    """Read the input table in any format the readers accept (CSV, Parquet, GPX, NMEA)."""
    from .._io.read import load_table

    return load_table(path, fmt, None, reading)


@click.command()
@click.argument(
    "input_path", metavar="INPUT", type=click.Path(exists=True, dir_okay=False, path_type=Path)
)
@option(
    "--protocol",
    type=click.Choice(["grad", "gnss", "sensor-grid"]),
    required=True,
    help="grad: position faults (paper Table 1); gnss: grad plus the faults real receivers "
    "make (freeze, drift, multipath, outage); sensor-grid: speed/accel/yaw-rate faults",
)
@option(
    "--row",
    metavar="NAME",
    help="sensor-grid row, e.g. instant-25, bias-5-3, drift-4-20, or mixed (default)",
)
@option(
    "--constant",
    type=click.Choice(["stuck", "offset"]),
    default="stuck",
    help="sensor-grid: a constant fault holds the reading at x(t0)+u (stuck) or adds u (offset)",
)
@option("--seed", type=int, default=0, help="random seed; same seed, same output bytes")
@option("--scale", type=float, default=1.0, help="multiplies every fault magnitude")
@option(
    "-o",
    "--output",
    "output",
    path="file",
    required=True,
    help="output CSV: the input columns (corrupted) plus label columns",
)
@column_options
def inject(
    input_path: Path,
    protocol: str,
    row: str | None,
    constant: str,
    seed: int,
    scale: float,
    output: Path,
    fmt: str | None,
    **cols: Any,
) -> None:
    """Inject seeded faults into INPUT and write the corrupted track with labels.

    Prints the achieved share of faulty points (percent of rows) per channel,
    time type and bias type. Protocols are defined in docs/protocols.md.
    """
    from rich.console import Console
    from rich.table import Table as RichTable

    from .._data.inject import (
        gnss_rates,
        grad_rates,
        inject_gnss,
        inject_grad,
        inject_sensor_grid,
        sensor_grid_rates,
    )

    columns: ColumnMap = column_map(cols)
    reading = read_options(cols)
    unsupported = [o for o in reading.given if o != "skip_rows"]
    if unsupported:
        # The faults are written into the input's own columns, in the input's own
        # units and notation: converting them on reading would change what is written.
        raise click.UsageError(
            f"{', '.join(reading.name(o) for o in unsupported)}: not supported by inject, which "
            "writes the values back as the input has them; convert the file first"
        )
    if protocol != "sensor-grid" and row is not None:
        raise click.UsageError("--row applies to --protocol sensor-grid only")
    with click_errors():
        table = _read_input(input_path, fmt, reading)
        table.frame.attrs["source"] = table.source
        if protocol == "grad":
            labelled = inject_grad(table.frame, seed=seed, scale=scale, columns=columns)
            rates = grad_rates(labelled)
        elif protocol == "gnss":
            labelled = inject_gnss(table.frame, seed=seed, scale=scale, columns=columns)
            rates = gnss_rates(labelled)
        else:
            labelled = inject_sensor_grid(
                table.frame,
                row=row or "mixed",
                seed=seed,
                scale=scale,
                columns=columns,
                constant=constant,
            )
            rates = sensor_grid_rates(labelled)
    from .._io.read import write_table

    write_table(labelled, output)
    title = f"achieved fault rates, % of {len(labelled)} rows ({protocol})"
    shown = RichTable(title=title + (", and episodes" if protocol == "gnss" else ""))
    shown.add_column("")
    for c in rates.columns:
        shown.add_column(str(c), justify="right")
    for name, values in rates.iterrows():
        shown.add_row(
            str(name), *[f"{v:.0f}" if c == "episodes" else f"{v:.2f}" for c, v in values.items()]
        )
    Console().print(shown)
    click.echo(f"wrote {output}")

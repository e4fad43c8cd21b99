"""``gradgps tune-rema``: grid-search REMA and time-classifier parameters on injected data."""

from __future__ import annotations

import json
from pathlib import Path

import click

from .errors import click_errors
from .options import option

__all__ = ["tune_rema"]


@click.command("tune-rema")
@option(
    "--protocol",
    type=click.Choice(["grad"]),
    default="grad",
    help="fault protocol (position faults with per-channel labels)",
)
@option("--dataset", type=click.Choice(["driveplotr", "tuc", "simulated"]), required=True)
@option(
    "--split",
    type=click.Choice(["train", "validation", "test"]),
    default="validation",
    help="split to tune on (never tune on test)",
)
@option(
    "--seeds",
    default="0,1,2",
    metavar="S[,S...]",
    help="injection seeds, pooled (several draws make the choice less lucky)",
)
@option("--mode", type=click.Choice(["trend", "paper"]), default="trend", help="REMA mode to tune")
@option(
    "--speed-heading/--no-speed-heading",
    default=True,
    help="trend mode: predict steps from reported speed and heading",
)
@option(
    "--data-dir",
    path="dir",
    help="folder with the shared drives; default $GRADGPS_DATA, then ../shared/data",
)
@option(
    "--grid",
    "grid_path",
    path="existing file",
    help='JSON object of REMA parameter lists, e.g. {"min_margin": [5, 8]} '
    "(default: the built-in grid, about 15,000 combinations)",
)
@option(
    "--table",
    "table_path",
    path="file",
    help="also write every REMA combination's scores here (CSV)",
)
@option(
    "-o",
    "--output",
    path="file",
    required=True,
    help="JSON file for the best settings (gradgps bench --rema-params FILE)",
)
def tune_rema(
    protocol: str,
    dataset: str,
    split: str,
    seeds: str,
    mode: str,
    speed_heading: bool,
    data_dir: Path | None,
    grid_path: Path | None,
    table_path: Path | None,
    output: Path,
) -> None:
    """Inject faults into a split, grid-search REMA (per-channel F1) then the time classifier."""
    from .._train.tune_rema import tune_on_dataset

    try:
        seed_list = [int(v) for v in seeds.split(",") if v.strip()]
    except ValueError as exc:
        raise click.BadParameter(
            f"expected integers separated by commas, got {seeds!r}", param_hint="--seeds"
        ) from exc
    grid = None
    if grid_path is not None:
        try:
            grid = json.loads(grid_path.read_text())
        except json.JSONDecodeError as exc:
            raise click.BadParameter(
                f"{grid_path} is not valid JSON: {exc}", param_hint="--grid"
            ) from exc
        if not isinstance(grid, dict) or not all(isinstance(v, list) and v for v in grid.values()):
            raise click.BadParameter(
                f"{grid_path} must hold an object of non-empty lists", param_hint="--grid"
            )
    with click_errors():
        settings, rema_table, _ = tune_on_dataset(
            dataset,
            split=split,
            seeds=seed_list,
            mode=mode,
            use_speed_heading=speed_heading,
            grid=grid,
            data_dir=data_dir,
            progress=True,
        )
    output.write_text(json.dumps(settings, indent=2) + "\n")
    if table_path is not None:
        rema_table.to_csv(table_path, index=False)
    scores = settings["scores"]
    click.echo(
        f"{protocol} on {dataset}/{split} (seeds {seeds}), {len(rema_table)} REMA combinations: "
        f"channel anomaly F1 {scores['channel_f1_anomaly']:.3f}, normal F1 "
        f"{scores['channel_f1_normal']:.3f}; time type accuracy {scores['time_type_accuracy']:.3f}"
    )
    click.echo(f"wrote {output}")

"""``gradgps calibrate``: choose a recipe model's thresholds per sampling rate anew.

``gradgps train --dataset recipe`` does this itself after training; this
command redoes only this step on a model directory it wrote (the weights are
untouched; the members' pooled thresholds stay in ``thresholds.pooled``).
"""

from __future__ import annotations

from pathlib import Path

import click

from .options import option

__all__ = ["calibrate"]


@click.command()
@click.argument(
    "model_dir", type=click.Path(exists=True, file_okay=False, path_type=Path), metavar="MODEL"
)
@option(
    "--data-dir",
    path="dir",
    help="folder of the real data sets (default $GRADGPS_DATA, then ../shared/data)",
)
@option(
    "--floor",
    type=click.FloatRange(0.5, 1.0, max_open=True),
    default=0.99,
    help="normal recall every group of validation drives must keep",
)
def calibrate(model_dir: Path, data_dir: Path | None, floor: float) -> None:
    """Choose MODEL's thresholds per sampling rate on the training recipe's validation drives.

    Per band (fixes faster than every 1.5 s, and that or slower): the best
    validation F1 that keeps normal recall at --floor on every group of drives
    (each real data set, the simulated drives at each rate), not only on their
    pool; the faults are injected three times, and a group's normal recall is
    the median of its three. MODEL must have been trained with `gradgps train
    --dataset recipe`.
    """
    import json

    from .._train.calibrate import calibrate_model, describe_thresholds
    from .._train.recipe import recipe_faults, recipe_tables

    try:
        source = json.loads((model_dir / "config.json").read_text())["training"]["data"]["source"]
    except (OSError, ValueError, KeyError, TypeError):
        source = ""
    if not str(source).startswith("recipe"):
        raise click.UsageError(
            f"{model_dir}: not a model trained with `gradgps train --dataset recipe` "
            "(its config.json names no recipe source); its thresholds stay as trained"
        )

    tables = recipe_tables("validation", data_dir=data_dir)
    click.echo(
        describe_thresholds(calibrate_model(model_dir, tables, recipe_faults(), floor=floor))
    )
    click.echo(f"wrote {model_dir / 'config.json'}")

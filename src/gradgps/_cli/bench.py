"""``gradgps bench``: score detectors on a data split with injected faults."""

from __future__ import annotations

import json
from pathlib import Path

import click

__all__ = ["bench"]


def _fmt(value: object) -> str:
    return "-" if value is None else f"{value:.3f}" if isinstance(value, float) else str(value)


@click.command()
@click.option(
    "--protocol",
    type=click.Choice(["grad", "sensor-grid"]),
    default=None,
    help="fault protocol (docs/protocols.md); required unless --suite",
)
@click.option(
    "--suite",
    type=click.Choice(["peers"]),
    default=None,
    help="peers: GRAD next to the tools users would pick instead (extra 'peers'), "
    "the table of benchmarks/peers.py on --dataset's test split",
)
@click.option("--dataset", type=click.Choice(["driveplotr", "tuc", "simulated"]), required=True)
@click.option(
    "--split", type=click.Choice(["train", "validation", "test"]), default="test", show_default=True
)
@click.option("--seed", type=int, default=0, show_default=True, help="injection seed")
@click.option(
    "--scale", type=float, default=1.0, show_default=True, help="multiplies every fault magnitude"
)
@click.option(
    "--detector",
    "detectors",
    default=None,
    metavar="NAME[,NAME...]",
    help="detectors to score, comma-separated: speed-gate, rema, rema-paper, grad "
    "(GRAD trained on the dataset's train split), grad-default (the shipped model), "
    "the peers (gradgps bench --suite peers lists them); required unless --suite",
)
@click.option(
    "--data-dir",
    type=click.Path(file_okay=False, path_type=Path),
    default=None,
    help="folder with the shared drives; default $GRADGPS_DATA, then ../shared/data",
)
@click.option(
    "--rema-params",
    type=click.Path(dir_okay=False, exists=True, path_type=Path),
    default=None,
    help="settings for detector 'rema' written by gradgps tune-rema (default: built-in)",
)
@click.option(
    "--model",
    type=click.Path(file_okay=False, exists=True, path_type=Path),
    default=None,
    help="model directory for detector 'grad' (default: trained on the train split and cached)",
)
@click.option(
    "--json",
    "json_path",
    type=click.Path(dir_okay=False, path_type=Path),
    default=None,
    help="write the full report here",
)
def bench(
    protocol: str | None,
    suite: str | None,
    dataset: str,
    split: str,
    seed: int,
    scale: float,
    detectors: str | None,
    data_dir: Path | None,
    rema_params: Path | None,
    model: Path | None,
    json_path: Path | None,
) -> None:
    """Inject faults into a data split, run detectors, print and save their scores."""
    from rich.console import Console
    from rich.progress import Progress
    from rich.table import Table

    from .._eval.bench import bench_units, run_bench
    from .._exceptions import GradGPSError

    if suite == "peers":
        from .peers import peers_suite

        peers_suite(dataset, data_dir, json_path)
        return
    if protocol is None or detectors is None:
        raise click.UsageError("--protocol and --detector are required unless --suite is given")

    names = [d.strip() for d in detectors.split(",") if d.strip()]
    console = Console(stderr=True)
    try:
        with Progress(console=console, transient=True) as progress:
            task = progress.add_task("benchmark", total=bench_units(protocol, names))
            report = run_bench(
                protocol,
                dataset,
                names,
                split=split,
                seed=seed,
                scale=scale,
                data_dir=data_dir,
                rema_params=rema_params,
                model=model,
                advance=lambda what: progress.update(task, advance=1, description=what),
            )
    except GradGPSError as exc:
        raise click.ClickException(str(exc)) from exc
    table = Table(title=f"{protocol} on {dataset}/{split}, seed {seed}")
    headers = [
        "detector",
        "row",
        "P",
        "R",
        "F1",
        "F1 norm",
        "evt R",
        "delay",
        "FA/h",
        "bias acc",
        "time acc",
        "rec m",
        "corr m",
        "us/pt",
    ]
    for h in headers:
        table.add_column(h, justify="left" if h in ("detector", "row") else "right")
    for name, res in report["results"].items():
        blocks = {"grad": res} if protocol == "grad" else res
        for row, b in blocks.items():
            table.add_row(
                name,
                row,
                *[
                    _fmt(v)
                    for v in (
                        b["anomaly"]["precision"],
                        b["anomaly"]["recall"],
                        b["anomaly"]["f1"],
                        b["normal"]["f1"],
                        b["event_recall"],
                        b["detection_delay_median"],
                        b["false_alarms_per_hour"],
                        b["bias_type_accuracy"],
                        b["time_type_accuracy"],
                        b["recovery_rmse_m"],
                        b["corrupted_rmse_m"],
                        b["us_per_point"],
                    )
                ],
            )
    out = Console()
    # A report table is read whole: never squeeze it below a readable width.
    wide = Console(width=max(out.width, 140))
    wide.print(table)
    for name, res in report["results"].items():
        for kind in ("bias", "time"):
            cm = res.get(f"{kind}_type_confusion") if protocol == "grad" else None
            if not cm:
                continue
            shown = Table(
                title=f"{name}: {kind} type of detected faults (rows true, columns predicted)"
            )
            labels = list(next(iter(cm.values())))
            shown.add_column("")
            for label in labels:
                shown.add_column(label, justify="right")
            for true_label, counts in cm.items():
                shown.add_row(true_label, *[str(counts[label]) for label in labels])
            wide.print(shown)
    if json_path is not None:
        json_path.write_text(json.dumps(report, indent=2) + "\n")
        click.echo(f"wrote {json_path}")

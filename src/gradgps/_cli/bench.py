"""``gradgps bench``: score detectors on a data split with injected faults."""

from __future__ import annotations

import json
from pathlib import Path

import click

from .options import option

__all__ = ["bench"]


def _robustness(
    detector: str,
    train_dataset: str | None,
    data_dir: Path | None,
    model: Path | None,
    json_path: Path | None,
) -> None:
    """``--suite robustness``: run the suite, print its matrix (Markdown), save the JSON."""
    import shlex

    from rich.console import Console
    from rich.progress import Progress

    from .._eval.bench import make_detector
    from .._eval.robustness import ROBUSTNESS_DATASETS, robustness_markdown, run_robustness
    from .._exceptions import GradGPSError

    try:
        # grad-default with --model: that model in place of the shipped one, i.e. 'grad'.
        det = make_detector(
            "grad" if detector == "grad-default" and model is not None else detector,
            dataset=train_dataset or "driveplotr",
            data_dir=data_dir,
            model=model,
        )
        with Progress(console=Console(stderr=True), transient=True) as progress:
            task = progress.add_task("robustness", total=None)
            report = run_robustness(
                det,
                detector,
                model=model,
                datasets=ROBUSTNESS_DATASETS,
                data_dir=data_dir,
                advance=lambda what: progress.update(task, advance=1, description=what),
            )
    except GradGPSError as exc:
        raise click.ClickException(str(exc)) from exc
    words = ["gradgps", "bench", "--suite", "robustness", "--detector", detector]
    words += ["--model", str(model)] if model is not None else []
    words += ["--dataset", train_dataset] if train_dataset is not None else []
    words += ["--data-dir", str(data_dir)] if data_dir is not None else []
    words += ["--json", str(json_path)] if json_path is not None else []
    command = shlex.join(words)
    click.echo("\n".join(robustness_markdown(report, command)))
    if json_path is not None:
        json_path.write_text(json.dumps(report, indent=1) + "\n")
        click.echo(f"wrote {json_path}")


def _fmt(value: object) -> str:
    return "-" if value is None else f"{value:.3f}" if isinstance(value, float) else str(value)


@click.command()
@option(
    "--suite",
    type=click.Choice(["robustness"]),
    help="run a whole suite instead of one protocol on one data set: 'robustness' = every "
    "real data set's test split x column variants x rates (see gradgps._eval.robustness); "
    "--dataset then names where detectors that need training are trained (default driveplotr)",
)
@option(
    "--protocol",
    type=click.Choice(["grad", "sensor-grid"]),
    help="fault protocol (docs/protocols.md); required without --suite",
)
@option(
    "--dataset",
    type=click.Choice(["driveplotr", "tuc", "simulated"]),
    help="data set; required without --suite",
)
@option("--split", type=click.Choice(["train", "validation", "test"]), default="test")
@option("--seed", type=int, default=0, help="injection seed")
@option("--scale", type=float, default=1.0, help="multiplies every fault magnitude")
@option(
    "--detector",
    "detectors",
    metavar="NAME[,NAME...]",
    help="detectors to score, comma-separated: speed-gate, rema, rema-paper, grad "
    "(GRAD trained on the dataset's train split), grad-default (the shipped model); "
    "required without --suite, one name with --suite (default grad-default)",
)
@option(
    "--data-dir",
    path="dir",
    help="folder with the shared drives; default $GRADGPS_DATA, then ../shared/data",
)
@option(
    "--rema-params",
    path="existing file",
    help="settings for detector 'rema' written by gradgps tune-rema (default: built-in)",
)
@option(
    "--model",
    path="existing dir",
    help="model directory for detector 'grad' (default: trained on the train split and "
    "cached); with --suite also for 'grad-default' (a model to measure instead of the shipped one)",
)
@option("--json", "json_path", path="file", help="write the full report here")
def bench(
    suite: str | None,
    protocol: str | None,
    dataset: str | None,
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

    if suite == "robustness":
        _robustness(detectors or "grad-default", dataset, data_dir, model, json_path)
        return
    for value, flag in (
        (protocol, "--protocol"),
        (dataset, "--dataset"),
        (detectors, "--detector"),
    ):
        if value is None:
            raise click.UsageError(f"missing option '{flag}' (needed without --suite)")
    assert protocol is not None
    assert dataset is not None
    assert detectors is not None
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

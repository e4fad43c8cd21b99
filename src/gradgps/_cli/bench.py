"""``gradgps bench``: score detectors on a data split with injected faults."""

from __future__ import annotations

import contextlib
import json
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import click

from .errors import click_errors
from .options import option

__all__ = ["bench"]


@contextlib.contextmanager
def _step_progress(label: str, total: int | None) -> Iterator[Callable[[str], None]]:
    """A transient progress bar on stderr, and the ``advance(what)`` callback that the
    suite runners (:func:`run_bench`, :func:`run_robustness`) take: one unit per
    finished step, the bar showing what it was."""
    from rich.console import Console
    from rich.progress import Progress

    with Progress(console=Console(stderr=True), transient=True) as progress:
        task = progress.add_task(label, total=total)
        yield lambda what: progress.update(task, advance=1, description=what)


def _real_drive_detector(
    detector: str, train_dataset: str | None, data_dir: Path | None, model: Path | None
) -> Any:
    """The detector a whole-suite run scores: ``grad-default`` with ``--model`` is that model
    in place of the shipped one (i.e. ``grad``); detectors that need training are trained
    on ``train_dataset`` (default DrivePlotR)."""
    from .._eval.bench import make_detector

    return make_detector(
        "grad" if detector == "grad-default" and model is not None else detector,
        dataset=train_dataset or "driveplotr",
        data_dir=data_dir,
        model=model,
    )


def _report(
    words: list[str],
    options: dict[str, Any],
    markdown: Callable[[dict[str, Any], str], list[str]],
    report: dict[str, Any],
    json_path: Path | None,
) -> None:
    """Print a suite's Markdown with the command that reproduces it (``words`` then every
    option that is set, ``--json`` last) and save its JSON."""
    import shlex

    for flag, value in options.items():
        words += [flag, str(value)] if value is not None else []
    words += ["--json", str(json_path)] if json_path is not None else []
    click.echo("\n".join(markdown(report, shlex.join(words))))
    if json_path is not None:
        json_path.write_text(json.dumps(report, indent=1) + "\n")
        click.echo(f"wrote {json_path}")


def _robustness(
    detector: str,
    train_dataset: str | None,
    data_dir: Path | None,
    model: Path | None,
    draws: int,
    json_path: Path | None,
) -> None:
    """``--suite robustness``: run the suite, print its matrix (Markdown), save the JSON."""
    from .._eval.robustness import robustness_markdown, run_robustness

    with click_errors():
        det = _real_drive_detector(detector, train_dataset, data_dir, model)
        with _step_progress("robustness", None) as advance:
            report = run_robustness(
                det, detector, model=model, data_dir=data_dir, advance=advance, draws=draws
            )
    _report(
        ["gradgps", "bench", "--suite", "robustness", "--detector", detector],
        {
            "--model": model,
            "--dataset": train_dataset,
            "--data-dir": data_dir,
            "--draws": draws if draws > 1 else None,
        },
        robustness_markdown,
        report,
        json_path,
    )


def _gnss(
    detector: str,
    train_dataset: str | None,
    data_dir: Path | None,
    model: Path | None,
    seed: int,
    scale: float,
    json_path: Path | None,
) -> None:
    """``--protocol gnss``: every real test split, positions only and with its columns."""
    from .._eval.gnss import gnss_markdown, run_gnss_bench
    from .._eval.robustness import ROBUSTNESS_DATASETS

    with click_errors():
        det = _real_drive_detector(detector, train_dataset, data_dir, model)
        with _step_progress("gnss", 2 * len(ROBUSTNESS_DATASETS)) as advance:
            report = run_gnss_bench(
                det,
                detector,
                model=model,
                data_dir=data_dir,
                seed=seed,
                scale=scale,
                advance=advance,
            )
    _report(
        ["gradgps", "bench", "--protocol", "gnss", "--detector", detector],
        {
            "--model": model,
            "--dataset": train_dataset,
            "--seed": seed or None,
            "--scale": f"{scale:g}" if scale != 1.0 else None,
            "--data-dir": data_dir,
        },
        gnss_markdown,
        report,
        json_path,
    )


def _fmt(value: object) -> str:
    return "-" if value is None else f"{value:.3f}" if isinstance(value, float) else str(value)


@click.command()
@option(
    "--suite",
    type=click.Choice(["robustness", "peers"]),
    help="run a whole suite instead of one protocol on one data set: 'robustness' = every "
    "real data set's test split x column variants x rates (see gradgps._eval.robustness); "
    "--dataset then names where detectors that need training are trained (default "
    "driveplotr); 'peers' = GRAD next to the tools users would pick instead (extra "
    "'peers'), the table of benchmarks/peers.py on --dataset's test split",
)
@option(
    "--protocol",
    type=click.Choice(["grad", "gnss", "sensor-grid"]),
    help="fault protocol (docs/protocols.md); required without --suite. 'gnss' runs on "
    "every real data set's test split, positions only and with its columns (--dataset "
    "then names where detectors that need training are trained; one --detector, default "
    "grad-default)",
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
    "(GRAD trained on the dataset's train split), grad-default (the shipped model), "
    "kf, cnn, cnn-kf, lstm-cnn, waved (trained baselines), "
    "the peers (see --suite peers); required without --suite, one name with "
    "--suite robustness (default grad-default)",
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
@option(
    "--per-row",
    is_flag=True,
    help="sensor-grid: train and threshold every trained detector on each row (one experiment "
    "per row) instead of once on 'mixed'",
)
@option(
    "--constant",
    type=click.Choice(["stuck", "offset"]),
    default="stuck",
    help="sensor-grid: a constant fault holds the reading at x(t0)+u (stuck) or adds u (offset)",
)
@option(
    "--fix-speed",
    is_flag=True,
    help="sensor-grid: the speed derived from the fixes as a second speed channel for every detector",
)
@option(
    "--window",
    minimum=1,
    default=10,
    help="steps per window of the window F1 (a window is anomalous if any step is)",
)
@option(
    "--rows",
    default=None,
    metavar="ROW[,ROW...]",
    help="sensor-grid: only these rows (default: all 19 and mixed)",
)
@option(
    "--draws",
    minimum=1,
    default=1,
    help="--suite robustness: also score protocol grad with seeds 1..N-1 in every cell and "
    "print the spread over the N fault draws (the verdicts stay seed 0's)",
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
    per_row: bool,
    constant: str,
    fix_speed: bool,
    window: int,
    rows: str | None,
    draws: int,
    json_path: Path | None,
) -> None:
    """Inject faults into a data split, run detectors, print and save their scores."""
    from rich.console import Console
    from rich.table import Table

    from .._eval.bench import bench_units, run_bench

    if suite == "robustness":
        _robustness(detectors or "grad-default", dataset, data_dir, model, draws, json_path)
        return
    if suite is None and protocol == "gnss":
        if detectors is not None and "," in detectors:
            raise click.UsageError("--protocol gnss takes one --detector")
        _gnss(detectors or "grad-default", dataset, data_dir, model, seed, scale, json_path)
        return
    if suite == "peers":
        from .peers import peers_suite

        if dataset is None:
            raise click.UsageError("--suite peers needs --dataset")
        peers_suite(dataset, data_dir, json_path)
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
    row_names = None if rows is None else [r.strip() for r in rows.split(",") if r.strip()]
    with click_errors():
        total = bench_units(protocol, names) if row_names is None else len(row_names) * len(names)
        with _step_progress("benchmark", total) as advance:
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
                per_row=per_row,
                constant=constant,
                fix_speed=fix_speed,
                window=window,
                rows=row_names,
                advance=advance,
            )
    table = Table(title=f"{protocol} on {dataset}/{split}, seed {seed}")
    headers = [
        "detector",
        "row",
        "P",
        "R",
        "F1",
        "F1 norm",
        "R norm",
        "win F1",
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
                        b["normal"]["recall"],
                        b["window"]["anomaly"]["f1"],
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
    wide = Console(width=max(out.width, 170))
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

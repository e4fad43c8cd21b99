"""``gradgps demo`` (and ``make demo``): the main job end to end on built-in data.

Simulates drives (no external data), injects protocol ``grad`` faults,
detects them with the default model shipped in the package, prints the
scores a user would ask for first, and writes everything to ``--out``: the
corrupted drives with labels and the detector's columns (``detections.csv``),
the scores (``metrics.json``) and, with matplotlib installed, the HTML
report (``report.html``: track, flagged fixes, REMA bounds, summary).
"""

from __future__ import annotations

from pathlib import Path

import click

from .options import option

__all__ = ["demo"]


@click.command()
@option("--tracks", type=int, default=10, help="simulated drives")
@option("--minutes", type=float, default=10.0, help="minutes per drive")
@option("--rate", "rate_hz", type=float, default=1.0, help="fixes per second")
@option(
    "--seed",
    type=int,
    default=0,
    help="seed of the fault injection (the drives use the simulated test split's seed)",
)
@option(
    "-o",
    "--output",
    "--out",
    "out_dir",
    path="dir",
    default=Path("out/demo"),
    help="folder for the outputs",
)
@option(
    "--report", "report_path", path="file", help="HTML report to write  [default: OUT/report.html]"
)
def demo(
    tracks: int, minutes: float, rate_hz: float, seed: int, out_dir: Path, report_path: Path | None
) -> None:
    """Simulate drives, inject faults, detect them with the default model, print the scores."""
    import json
    import time

    import pandas as pd
    from rich.console import Console
    from rich.table import Table

    from .._data.datasets import SIMULATED_SPLITS
    from .._data.inject import inject_grad
    from .._data.simulator import simulate_fleet
    from .._eval.metrics import class_scores, confusion_matrix, rmse_m
    from .._grad.detector import Detector
    from .._io.read import write_table
    from .._tracks.track import to_fixes

    console = Console(highlight=False)
    drive_seed = SIMULATED_SPLITS["test"][3]
    clean = simulate_fleet(tracks, minutes, rate_hz, drive_seed)
    labelled = inject_grad(clean, seed=seed)
    fixes = to_fixes(labelled)
    console.print(
        f"simulated {tracks} drives x {minutes:g} min at {rate_hz:g} Hz "
        f"({len(fixes):,} fixes), injected protocol grad faults (seed {seed}): "
        f"{int(labelled['label_anomaly'].sum()):,} faulty fixes"
    )
    detector = Detector()
    detector.detect(fixes.iloc[:50])  # load the compiled kernels before timing
    started = time.perf_counter()
    result = detector.detect(fixes)
    us_per_point = 1e6 * (time.perf_counter() - started) / max(len(fixes), 1)

    truth = labelled["label_anomaly"].to_numpy()
    flagged = result["anomaly"].to_numpy() == 1
    scores = class_scores(truth, flagged)
    table = Table(title="detection, per fix")
    for col in ("class", "precision", "recall", "F1", "support"):
        table.add_column(col, justify="right")
    for name in ("anomaly", "normal"):
        s = scores[name]
        support = int(truth.sum()) if name == "anomaly" else int((truth == 0).sum())
        table.add_row(
            name, f"{s['precision']:.4f}", f"{s['recall']:.4f}", f"{s['f1']:.4f}", f"{support:,}"
        )
    console.print(table)
    both = flagged & (truth == 1)
    confusions = {}
    for kind, labels in (
        ("bias", ["noise", "jump"]),
        ("time", ["transient", "intermittent", "permanent"]),
    ):
        cm = confusion_matrix(
            labelled[f"label_{kind}"].to_numpy()[both],
            result[f"{kind}_type"].to_numpy()[both],
            labels,
        )
        confusions[kind] = cm
        shown = Table(title=f"{kind} type of detected faults (rows: true, columns: predicted)")
        shown.add_column("")
        for c in cm.columns:
            shown.add_column(str(c), justify="right")
        for true_label, counts in cm.iterrows():
            shown.add_row(str(true_label), *[str(int(v)) for v in counts])
        console.print(shown)
    faulty = truth == 1
    repairable = faulty & (labelled["label_time"].to_numpy() != "permanent")
    rec = rmse_m(
        result["lat_clean"],
        result["lon_clean"],
        labelled["lat_true"],
        labelled["lon_true"],
        repairable,
    )
    cor = rmse_m(fixes["lat"], fixes["lon"], labelled["lat_true"], labelled["lon_true"], repairable)
    alerts = int(result["alert"].sum())
    console.print(
        f"recovery on transient/intermittent faults: RMSE {rec:.1f} m after repair, "
        f"{cor:.1f} m as corrupted; {alerts:,} alerts raised (permanent faults)"
    )
    console.print(f"speed: {us_per_point:.2f} us per fix (batch, one core)")

    out_dir.mkdir(parents=True, exist_ok=True)
    write_table(
        pd.concat([labelled, result.reset_index(drop=True)], axis=1), out_dir / "detections.csv"
    )
    metrics = {
        "fixes": len(fixes),
        "scores": scores,
        "bias_confusion": confusions["bias"].to_dict(),
        "time_confusion": confusions["time"].to_dict(),
        "recovery_rmse_m": rec,
        "corrupted_rmse_m": cor,
        "alerts": alerts,
        "us_per_point": us_per_point,
    }
    (out_dir / "metrics.json").write_text(json.dumps(metrics, indent=2, default=float) + "\n")
    console.print(
        f"outputs: {out_dir / 'detections.csv'} (every fix with labels and verdicts), "
        f"{out_dir / 'metrics.json'} (these scores)"
    )
    try:
        import matplotlib  # noqa: F401
    except ImportError:
        console.print("no HTML report: it needs matplotlib (pip install 'gradgps[report]')")
        return
    from .report import write_report_outputs

    write_report_outputs(
        report_path or out_dir / "report.html",
        None,
        fixes,
        result,
        detector,
        us_per_point * 1e-6 * len(fixes),
        f"gradgps demo: {tracks} simulated drives, protocol grad faults (seed {seed})",
        {
            "anomaly F1 vs injected labels": f"{scores['anomaly']['f1']:.4f}",
            "recovery RMSE (transient/intermittent)": f"{rec:.1f} m repaired, {cor:.1f} m corrupted",
        },
    )

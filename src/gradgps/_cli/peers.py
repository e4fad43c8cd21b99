"""``gradgps bench --suite peers``: the peers table on one data set (see ``benchmarks/peers.py``)."""

from __future__ import annotations

import json
from pathlib import Path

import click

from .errors import click_errors

__all__ = ["peers_suite"]


def _num(value: float | None, fmt: str) -> str:
    return "-" if value is None else format(value, fmt)


def peers_suite(dataset: str, data_dir: Path | None, json_path: Path | None) -> None:
    """Score GRAD and every peer on ``dataset``'s test split and print the table.

    Uses the committed tuned settings; a data set without them is tuned on
    its validation split first (kept in memory; ``python benchmarks/peers.py
    --tune`` writes them).
    """
    from rich.console import Console
    from rich.table import Table

    from .._baselines.peers import PEER_NAMES, TUNED_FILE
    from .._eval.peers import peers_table, tune_peers
    from .._grad.detector import Detector

    console = Console(stderr=True)
    with click_errors():
        tuned_all = json.loads(TUNED_FILE.read_text()) if TUNED_FILE.is_file() else {}
        tuned = tuned_all.get(dataset, {})
        if any(p not in tuned.get("positions", {}) for p in PEER_NAMES if p != "kalman-chi2-vel"):
            console.print(f"no tuned peer settings for {dataset}: tuning on its validation split")
            tuned = tune_peers(dataset, data_dir=data_dir, log=console.print)
        report = peers_table(dataset, tuned, Detector(), data_dir=data_dir, log=console.print)
    wide = Console(width=140)
    for variant, rows in report["variants"].items():
        table = Table(title=f"peers on {dataset}/test ({report['points']} fixes), {variant}")
        for h in (
            "method",
            "F1 split",
            "F1 whole",
            "F1/GRAD",
            "clean FA %",
            "batch us",
            "stream us",
        ):
            table.add_column(h, justify="left" if h == "method" else "right")
        for name, row in rows.items():
            table.add_row(
                name,
                _num(row["split"]["f1"], ".3f"),
                _num(row["whole_file"]["f1"], ".3f"),
                _num(row["f1_ratio_to_grad"], ".2f"),
                f"{row['clean_false_alarm_pct']:.1f}",
                _num(row["batch_us"], ".1f"),
                _num(row["stream_us"], ".1f"),
            )
        wide.print(table)
    if json_path is not None:
        json_path.write_text(json.dumps(report, indent=2) + "\n")
        click.echo(f"wrote {json_path}")

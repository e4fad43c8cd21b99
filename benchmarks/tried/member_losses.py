"""Each member's validation loss over its epochs, from a trained model's ``config.json``.

Why: a recipe change (more fault draws, longer drives) shows first in how far the
members' validation loss falls and where it bottoms out, on the same validation
sequences (the recipe's validation drives, injection seed 7), before any detector
figure: the shipped members' loss bottomed out at epochs 12-24 while their training
loss kept falling. Per member: its seed, the epoch it was kept at (the best by the
training's own rule), the lowest validation loss and its epoch, and the training and
validation loss at the last epoch. Run:

    python benchmarks/tried/member_losses.py MODEL_DIR [MODEL_DIR ...]
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path
from typing import Any

from gradgps._grad.model_io import CONFIG_FILE


def member_rows(config: dict[str, Any]) -> list[dict[str, float | int]]:
    """One row per member of ``config["training"]`` (a single network: one row)."""
    training = config["training"]
    members = training.get("members") or [
        {"seed": training["config"]["seed"], **training}  # one network, no members list
    ]
    rows: list[dict[str, float | int]] = []
    for m in members:
        history = m["history"]
        lowest = min(history, key=lambda e: e["val_loss"])
        rows.append(
            {
                "seed": int(m["seed"]),
                "kept_epoch": int(m["best_epoch"]),
                "lowest_val_loss": float(lowest["val_loss"]),
                "lowest_at": int(lowest["epoch"]),
                "last_train_loss": float(history[-1]["train_loss"]),
                "last_val_loss": float(history[-1]["val_loss"]),
            }
        )
    return rows


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("models", nargs="+", help="model directories")
    args = parser.parse_args()
    print(
        "| model | seed | kept epoch | lowest validation loss | at epoch "
        "| last training loss | last validation loss |"
    )
    print("|---|---|---|---|---|---|---|")
    for directory in args.models:
        config = json.loads((Path(directory) / CONFIG_FILE).read_text())
        for r in member_rows(config):
            print(
                f"| {directory} | {r['seed']} | {r['kept_epoch']} | {r['lowest_val_loss']:.4f} "
                f"| {r['lowest_at']} | {r['last_train_loss']:.4f} | {r['last_val_loss']:.4f} |"
            )


if __name__ == "__main__":
    main()

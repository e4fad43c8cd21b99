"""Merge model directories trained apart into one ensemble, as ``gradgps train --members N`` does.

Why: ``--members N`` trains its members one after the other in one process (about
13 minutes each for the recipe on one core). Trained one per core with
``--members 1 --seed S`` and merged here, N members take the time of one on N
cores. The members must come from the same recipe (same features, so the same
scaler: :func:`gradgps._train.torch_gru.merge_networks` refuses otherwise) and
may themselves be merged ensembles of equal size (a merge of merges is the mean
of all their members, with their units in another order). Thresholds: the
members' mean, as ``train_ensemble`` keeps them. The config is the first
directory's with the merged sizes and thresholds, and ``training.merged_from``
names the directories. Run:

    python benchmarks/merge_members.py OUT_DIR MODEL_DIR MODEL_DIR [MODEL_DIR ...]
"""

from __future__ import annotations

import argparse
import copy
from pathlib import Path

import numpy as np

from gradgps._exceptions import ConfigError
from gradgps._grad.model_io import export_torch, load_model, save_model
from gradgps._train.torch_gru import GRADNet, merge_networks, network_from_arrays


def load_network(directory: Path) -> tuple[GRADNet, dict]:
    """The torch network of a model directory, and its config."""
    weights, config = load_model(directory)
    scaler = config["scaler"]
    return network_from_arrays(weights, scaler["mean"], scaler["std"]), config


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("output", type=Path)
    parser.add_argument("members", type=Path, nargs="+")
    args = parser.parse_args()
    if len(args.members) < 2:
        raise SystemExit("merge_members.py: give at least two model directories to merge")
    loaded = [load_network(d) for d in args.members]
    sizes = {(c["architecture"]["hidden1"], c["architecture"]["hidden2"]) for _, c in loaded}
    if len(sizes) > 1:
        raise ConfigError(f"members of different sizes {sorted(sizes)}: merge equal ensembles only")
    merged = merge_networks([net for net, _ in loaded])
    config = copy.deepcopy(loaded[0][1])
    for key in ("format_version", "weights_file", "weights_sha256"):
        config.pop(key, None)
    config["architecture"]["hidden1"] = merged.gru1.hidden_size
    config["architecture"]["hidden2"] = merged.gru2.hidden_size
    for key in config["thresholds"]:
        config["thresholds"][key] = float(np.mean([c["thresholds"][key] for _, c in loaded]))
    config.setdefault("training", {})["merged_from"] = [str(d) for d in args.members]
    save_model(args.output, export_torch(merged), config)
    print(f"wrote {args.output}: thresholds {config['thresholds']}")


if __name__ == "__main__":
    main()

"""Feed-window (the paper's W = 10 and 50) versus streaming GRU: accuracy and speed.

    python benchmarks/gru_modes.py --json OUT.json [--dataset driveplotr] [--budget 180]

Trains three networks on the same features and labels (protocol ``grad``
injected into the train split, validation split for early stopping, as
``gradgps train`` does), scores each on the test split injected with seed 0,
and times the network alone per point (features excluded: they are the same
for all three). Window mode re-runs the GRU over the last W points for every
point, O(W); streaming carries the hidden state, O(1).
"""

from __future__ import annotations

import os

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS", "NUMBA_NUM_THREADS"):
    os.environ[_var] = "1"

import argparse  # noqa: E402
import datetime  # noqa: E402
import json  # noqa: E402
import platform  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402

from gradgps._data.datasets import load_dataset  # noqa: E402
from gradgps._eval.metrics import class_scores  # noqa: E402
from gradgps._grad.gru import GRUModel  # noqa: E402
from gradgps._grad.model_io import export_torch  # noqa: E402
from gradgps._grad.pipeline import PipelineParams  # noqa: E402
from gradgps._train.grad import (  # noqa: E402
    GRAD_BIAS_CLASSES,
    GradTrainingSet,
    _sequences,
)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--json", type=Path, required=True)
    parser.add_argument("--dataset", default="driveplotr")
    parser.add_argument("--budget", type=float, default=180.0, help="training seconds per model")
    args = parser.parse_args()

    from gradgps._train.torch_gru import TrainConfig, train_model

    params = PipelineParams()
    spec = GradTrainingSet()
    train = _sequences([load_dataset(args.dataset, "train")], params, spec.seeds, spec.scales)
    val = _sequences([load_dataset(args.dataset, "validation")], params, (spec.val_seed,), (1.0,))
    test = _sequences([load_dataset(args.dataset, "test")], params, (0,), (1.0,))
    truth = np.concatenate([s[1] for s in test])
    results: dict[str, object] = {
        "command": f"python benchmarks/gru_modes.py --json {args.json} --dataset {args.dataset}",
        "machine": f"{platform.machine()} {os.cpu_count()} cores",
        "date": datetime.date.today().isoformat(),
        "dataset": args.dataset,
        "modes": {},
    }
    for name, mode, window in (
        ("stream", "stream", 10),
        ("window-10", "window", 10),
        ("window-50", "window", 50),
    ):
        cfg = TrainConfig(
            bias_classes=GRAD_BIAS_CLASSES,
            mode=mode,
            window=window,
            time_budget_s=args.budget,
            early_stopping="f1",
            patience=25,
            max_epochs=400,
            progress=False,
        )
        started = time.perf_counter()
        trained = train_model(train, val, cfg)
        train_s = time.perf_counter() - started
        net = GRUModel(
            export_torch(trained.network),
            trained.network.scaler_mean.numpy(),
            trained.network.scaler_std.numpy(),
            mode=mode,
            window=window,
        )
        net.predict(test[0][0][:20])  # compile
        started = time.perf_counter()
        prob = np.concatenate([net.predict(s[0]).anomaly for s in test])
        us = 1e6 * (time.perf_counter() - started) / truth.size
        scores = class_scores(truth, prob >= trained.anomaly_threshold)
        results["modes"][name] = {  # type: ignore[index]
            "anomaly_f1": scores["anomaly"]["f1"],
            "normal_f1": scores["normal"]["f1"],
            "us_per_point_network": us,
            "train_seconds": train_s,
            "best_epoch": trained.best_epoch,
            "stop_reason": trained.stop_reason,
        }
        print(name, results["modes"][name])  # type: ignore[index]
    args.json.write_text(json.dumps(results, indent=2) + "\n")


if __name__ == "__main__":
    main()

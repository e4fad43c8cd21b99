"""``make bench``: GRAD and the comparison baselines side by side; writes BENCHMARKS.md.

    python benchmarks/run_all.py [--quick] [--data-dir DIR] [--results DIR] [--markdown FILE]

Tables, each in its own process (one machine, one core: BLAS, numba and
torch threads pinned to 1 before anything is imported):

* ``grad-driveplotr``, ``grad-tuc``: protocol ``grad`` on the test split,
  normal and anomaly precision / recall / F1 per method (the paper's Table 2);
* ``sensor-grid``: the 19 rows of the paper's comparison table plus
  ``mixed`` on DrivePlotR, anomaly F1 per method;
* ``sweep``: protocol ``grad`` on DrivePlotR at ``--scale`` 0.25, 0.5, 1, 2;
* ``speed``: µs per point, batch ``detect`` and streaming ``update``;
* ``robustness``: ``gradgps bench --suite robustness`` with the shipped model
  (every real data set x column variant x rate, issue 13); written to
  ``results/robustness_grad-default.json`` and to its own block of
  BENCHMARKS.md (between ``<!-- robustness:start -->`` and
  ``<!-- robustness:end -->``) by the process that runs it, so
  ``python benchmarks/run_all.py --table robustness --json FILE`` alone
  refreshes that block.
* then ``benchmarks/peers.py``: GRAD next to the tools users would pick instead.

Every trained method (GRAD and the baselines) is trained on the data set's
train split with the same recipe and cached (``$GRADGPS_CACHE``), so a second
run only re-scores. Results go to ``benchmarks/results/bench_*.json``;
BENCHMARKS.md is rewritten only between ``<!-- bench:start -->`` and
``<!-- bench:end -->``, so other sections of that file stay.

``--quick`` runs the same code on tiny data (``--data-dir`` with small
DrivePlotR/TUC-shaped files), with a tiny training budget and the shipped GRAD
model, in seconds: the test suite checks the shape of what it writes.
"""

from __future__ import annotations

import os

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS", "NUMBA_NUM_THREADS"):
    os.environ[_var] = "1"

import argparse  # noqa: E402
import copy  # noqa: E402
import datetime  # noqa: E402
import json  # noqa: E402
import subprocess  # noqa: E402
import sys  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402
from typing import Any  # noqa: E402

from gradgps._eval.robustness import machine  # noqa: E402

REPO = Path(__file__).resolve().parents[1]
TABLES = ("grad-driveplotr", "grad-tuc", "sensor-grid", "sweep", "speed", "robustness")
POSITION_METHODS = ["grad", "grad-default", "rema", "speed-gate", "kf", "cnn", "cnn-kf", "lstm-cnn"]
SENSOR_METHODS = ["grad", "grad-f1", "kf", "cnn", "cnn-kf", "lstm-cnn", "waved"]
SENSOR_BASELINES = ["kf", "cnn", "cnn-kf", "lstm-cnn", "waved"]
#: Per-row experiments under sensor-grid: every trained method (GRAD and the
#: baselines alike) gets this recipe on each row: 3 injection seeds of the
#: train split, a 15-second wall budget, patience 10. 20 rows x (GRU, CNN,
#: LSTM-CNN) x 15 s keeps the table within about half an hour on 2 cores.
GRID_SEEDS = (101, 102, 103)
GRID_BUDGET_S = 15.0
GRID_PATIENCE = 10
#: Windows per epoch (validation, early stopping) for every window-trained method.
GRID_SAMPLES_PER_EPOCH = 20_000
#: Window of the window F1 (steps, the same for every detector).
GRID_WINDOW = 10
BASELINES = ["kf", "cnn", "cnn-kf", "lstm-cnn", "rema", "speed-gate"]
SCALES = (0.25, 0.5, 1.0, 2.0)
START, END = "<!-- bench:start -->", "<!-- bench:end -->"

# The paper's published numbers (grad-paper.tex). Never mixed with ours.
PAPER_TABLE2 = {  # Table 2: GRAD on MMITSS and Zurich (percent)
    "MMITSS": {"normal": (99.58, 99.11, 99.34), "anomaly": (96.57, 98.35, 97.45)},
    "Zurich": {"normal": (99.46, 99.09, 99.27), "anomaly": (96.39, 97.82, 97.10)},
}
PAPER_COLUMNS = ("KF", "CNN", "CNN-KF", "WAVED", "ML-C", "GRAD")
PAPER_GRID = {  # comparison table, overall F1 percent, columns PAPER_COLUMNS
    "instant-25": (48.5, 66.0, 67.4, 68.9, 70.2, 75.2),
    "instant-100": (85.3, 91.5, 91.7, 92.0, 93.8, 97.2),
    "instant-500": (97.3, 97.8, 97.8, 98.2, 99.1, 99.5),
    "instant-1000": (98.1, 98.4, 98.4, 98.5, 98.7, 99.7),
    "instant-10000": (99.8, 99.5, 99.5, 99.6, 99.4, 99.9),
    "constant-5-3": (95.0, 94.1, 94.5, 94.0, 94.7, 99.5),
    "constant-5-5": (96.7, 94.8, 95.2, 95.3, 95.6, 99.5),
    "constant-5-10": (97.3, 96.4, 97.0, 96.5, 97.5, 99.3),
    "constant-3-10": (94.6, 95.8, 96.2, 96.4, 97.2, 99.6),
    "constant-1-10": (85.1, 91.6, 92.7, 92.4, 94.6, 99.7),
    "bias-5-3": (95.7, 93.4, 94.2, 93.6, 94.8, 99.4),
    "bias-5-5": (96.0, 94.3, 94.9, 95.5, 95.7, 99.3),
    "bias-5-10": (96.6, 95.4, 96.7, 95.5, 97.4, 98.9),
    "bias-3-10": (94.8, 93.7, 95.5, 94.9, 96.1, 98.9),
    "bias-1-10": (86.9, 86.8, 90.0, 88.1, 90.6, 98.8),
    "drift-4-10": (93.4, 95.5, 96.1, 96.2, 97.5, 99.1),
    "drift-4-20": (93.8, 97.2, 97.4, 97.6, 97.7, 98.3),
    "drift-2-10": (87.9, 94.0, 94.2, 94.9, 95.6, 98.9),
    "drift-2-20": (86.7, 95.3, 95.9, 96.1, 96.1, 98.3),
}


# ----------------------------------------------------------------------------
# One table per process
# ----------------------------------------------------------------------------


def _recipe(quick: bool) -> Any:
    from gradgps._train.baselines import BaselineRecipe

    if not quick:
        return BaselineRecipe()
    return BaselineRecipe(
        seeds=(101,), time_budget_s=1.0, max_epochs=1, patience=1, max_samples_per_epoch=512
    )


def _grid_recipe(quick: bool) -> Any:
    """The per-row recipe of the sensor-grid table (see GRID_*)."""
    from dataclasses import replace

    base = _recipe(quick)
    if quick:
        return base
    return replace(
        base,
        seeds=GRID_SEEDS,
        time_budget_s=GRID_BUDGET_S,
        patience=GRID_PATIENCE,
        max_samples_per_epoch=GRID_SAMPLES_PER_EPOCH,
    )


def _grid(args: argparse.Namespace) -> dict[str, Any]:
    """sensor-grid on DrivePlotR: per-row experiments, second speed source, point + window F1."""
    from gradgps._eval.bench import run_bench

    rows = os.environ.get("GRADGPS_GRID_ROWS")  # tests and development: a subset of rows
    return run_bench(
        "sensor-grid",
        "driveplotr",
        SENSOR_METHODS,
        seed=0,
        data_dir=args.data_dir,
        recipe=_grid_recipe(args.quick),
        per_row=True,
        fix_speed=True,
        window=GRID_WINDOW,
        rows=None if not rows else rows.split(","),
    )


def _grad_model(quick: bool) -> Path | None:
    """``grad`` under protocol grad: trained on the data set (cached); quick: the shipped model."""
    if not quick:
        return None
    from gradgps._grad.detector import _default_model_dir

    return _default_model_dir()


def _bench(
    protocol: str, dataset: str, methods: list[str], args: argparse.Namespace, scale: float = 1.0
) -> dict[str, Any]:
    from gradgps._eval.bench import run_bench

    return run_bench(
        protocol,
        dataset,
        methods,
        seed=0,
        scale=scale,
        data_dir=args.data_dir,
        model=_grad_model(args.quick),
        recipe=_recipe(args.quick),
    )


def _speed(args: argparse.Namespace) -> dict[str, Any]:
    """µs per point on the DrivePlotR test split (protocol grad, seed 0): batch and streaming."""
    from gradgps._data.datasets import load_dataset
    from gradgps._data.inject import inject_grad
    from gradgps._eval.bench import make_detector
    from gradgps._tracks.track import to_fixes

    table = load_dataset("driveplotr", "test", data_dir=args.data_dir)
    cmap = to_fixes(table).attrs["columns"]
    fixes = to_fixes(inject_grad(table, seed=0, columns=cmap), cmap)
    out: dict[str, Any] = {"points": len(fixes)}
    for name in POSITION_METHODS:
        det = make_detector(
            name,
            dataset="driveplotr",
            data_dir=args.data_dir,
            model=_grad_model(args.quick) if name == "grad" else None,
            recipe=_recipe(args.quick),
        )
        fresh = copy.deepcopy(det)
        det.detect(fixes.iloc[:50])  # compile and warm caches
        batch = []
        for _ in range(3):
            began = time.perf_counter()
            det.detect(fixes)
            batch.append(time.perf_counter() - began)
        stream_us = None
        if hasattr(fresh, "update"):
            warm = copy.deepcopy(fresh)  # compile / load the per-point kernels first
            for row in fixes.iloc[:50].itertuples(index=False):
                warm.update(row.t, row.lat, row.lon, getattr(row, "speed", None))
            elapsed, count = 0.0, 0
            for _, rows in fixes.sort_values(["track", "t"]).groupby("track", sort=False):
                one = copy.deepcopy(fresh)
                cols = [rows[c].to_numpy(float) for c in ("t", "lat", "lon")]
                speed = rows["speed"].to_numpy(float) if "speed" in rows else None
                began = time.perf_counter()
                for i in range(len(rows)):
                    one.update(
                        cols[0][i], cols[1][i], cols[2][i], None if speed is None else speed[i]
                    )
                elapsed += time.perf_counter() - began
                count += len(rows)
            stream_us = 1e6 * elapsed / max(count, 1)
        out[name] = {
            "batch_us_per_point": 1e6 * min(batch) / len(fixes),
            "stream_us_per_point": stream_us,
        }
    return out


def run_table(name: str, args: argparse.Namespace) -> dict[str, Any]:
    if name == "grad-driveplotr":
        return _bench("grad", "driveplotr", POSITION_METHODS, args)
    if name == "grad-tuc":
        return _bench("grad", "tuc", POSITION_METHODS, args)
    if name == "sensor-grid":
        return _grid(args)
    if name == "sweep":
        return {
            str(s): _bench("grad", "driveplotr", POSITION_METHODS, args, scale=s) for s in SCALES
        }
    if name == "speed":
        return _speed(args)
    if name == "robustness":
        return robustness_table(args)
    raise SystemExit(f"unknown table {name!r}; known: {', '.join(TABLES)}")


# ----------------------------------------------------------------------------
# BENCHMARKS.md
# ----------------------------------------------------------------------------


def _f(value: float | None, pct: bool = False) -> str:
    if value is None:
        return "-"
    return f"{100 * value:.1f}" if pct else f"{value:.3f}"


def _grad_section(report: dict[str, Any], title: str) -> list[str]:
    lines = [
        f"### Protocol `grad`, {title} (test split, seed 0)",
        "",
        "| method | normal P | normal R | normal F1 | anomaly P | anomaly R | anomaly F1 |",
        "|---|---|---|---|---|---|---|",
    ]
    for name, block in report["results"].items():
        cells = [
            _f(block[c][m]) for c in ("normal", "anomaly") for m in ("precision", "recall", "f1")
        ]
        lines.append(f"| {name} | " + " | ".join(cells) + " |")
    return [*lines, ""]


def _grid_table(
    report: dict[str, Any], methods: list[str], rows: list[str], metric: str, with_paper: bool
) -> tuple[list[str], list[str]]:
    """One sensor-grid table (``metric``: ``point`` or ``window`` anomaly F1) and its verdicts."""
    paper_head = (
        " | " + " | ".join(f"SPMD, published: {c}" for c in PAPER_COLUMNS[:-1]) + " | paper: GRAD"
        if with_paper
        else ""
    )
    res = report["results"]
    reference = report.get("reference", {})
    lines = [
        f"| row | {' | '.join(methods)} | flag every reading | GRAD vs best baseline{paper_head} |",
        "|---" * (len(methods) + 3 + (len(PAPER_COLUMNS) if with_paper else 0)) + "|",
    ]
    verdicts = []
    for row in rows:
        blocks = {m: res[m][row] for m in methods}
        f1 = {
            m: (b["anomaly"] if metric == "point" else b["window"]["anomaly"])["f1"]
            for m, b in blocks.items()
        }
        others = {m: v for m, v in f1.items() if m in SENSOR_BASELINES and v is not None}
        best = max(others, key=lambda m: others[m]) if others else None
        g = f1.get("grad")
        if g is None or best is None:
            verdict = "-"
        else:
            diff = 100 * (g - others[best])
            verdict = f"leads by {diff:.1f}" if diff >= 0 else f"trails {best} by {-diff:.1f}"
            verdicts.append(
                f"{row} ({metric} F1): GRAD {100 * g:.1f}, best baseline {best} "
                f"{100 * others[best]:.1f} -> {'at or above' if diff >= 0 else 'BELOW'}"
            )
        key = "flag_all_f1" if metric == "point" else "flag_all_window_f1"
        cells = " | ".join(_f(f1[m], pct=True) for m in methods)
        cells += " | " + _f(reference.get(row, {}).get(key), pct=True)
        paper = PAPER_GRID.get(row)
        paper_cells = (
            " | " + " | ".join(f"{v:.1f}" for v in paper)
            if paper
            else " | " + " | ".join(["-"] * len(PAPER_COLUMNS))
        )
        lines.append(f"| {row} | {cells} | {verdict}{paper_cells if with_paper else ''} |")
    return lines, verdicts


def _sensor_section(report: dict[str, Any]) -> tuple[list[str], list[str]]:
    res = report["results"]
    methods = list(res)
    rows = list(next(iter(res.values())))
    window = report.get("window_steps", 10)
    setting = (
        (
            "per-row experiments (every trained method trained and thresholded on each row)"
            if report.get("per_row")
            else "one model per method trained on `mixed`"
        )
        + ("; second speed source: speed from the fixes" if report.get("fix_speed") else "")
        + f"; `constant` faults: {report.get('constant', 'stuck')}"
    )
    point, v_point = _grid_table(report, methods, rows, "point", True)
    win, v_win = _grid_table(report, methods, rows, "window", False)
    recall = ["| row | " + " | ".join(methods) + " |", "|---" * (len(methods) + 1) + "|"]
    for row in rows:
        recall.append(
            f"| {row} | " + " | ".join(_f(res[m][row]["normal"]["recall"]) for m in methods) + " |"
        )
    lines = [
        "### Protocol `sensor-grid`, DrivePlotR (test split, seed 0): anomaly F1 (%), point",
        "",
        f"Setting: {setting}. Columns **SPMD, published** are the numbers van Wyk et al. "
        "(2020) and Javed et al. (2021) published on the SPMD data set (10 Hz; in-vehicle "
        "speed, GPS speed, longitudinal acceleration), which the paper's comparison table "
        "reprints; **paper: GRAD** is the paper's own claim. None of them is measured on "
        "our data. *flag every reading*: the F1 of a detector that flags everything, "
        "the floor a useful detector must clear (long faults make it high).",
        "",
        *point,
        "",
        f"### Protocol `sensor-grid`: anomaly F1 (%), windows of {window} steps "
        "(a window is anomalous if any of its steps is; flagged if any step is flagged)",
        "",
        *win,
        "",
        "### Protocol `sensor-grid`: normal recall (share of clean readings left unflagged)",
        "",
        *recall,
        "",
    ]
    return lines, v_point + v_win


def _sweep_section(sweep: dict[str, Any], png: str) -> list[str]:
    methods = list(next(iter(sweep.values()))["results"])
    lines = [
        "### Magnitude sweep: protocol `grad`, DrivePlotR, anomaly F1 by `--scale`",
        "",
        "| method | " + " | ".join(f"× {s}" for s in sweep) + " |",
        "|---" * (len(sweep) + 1) + "|",
    ]
    for m in methods:
        lines.append(
            f"| {m} | "
            + " | ".join(_f(sweep[s]["results"][m]["anomaly"]["f1"]) for s in sweep)
            + " |"
        )
    return [*lines, "", f"![anomaly F1 by fault magnitude]({png})", ""]


def _plot_sweep(sweep: dict[str, Any], path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    scales = [float(s) for s in sweep]
    fig, ax = plt.subplots(figsize=(6, 4))
    for m in next(iter(sweep.values()))["results"]:
        values = [sweep[s]["results"][m]["anomaly"]["f1"] for s in sweep]
        ax.plot(scales, [float("nan") if v is None else v for v in values], marker="o", label=m)
    ax.set_xscale("log", base=2)
    ax.set_xlabel("fault magnitude scale (protocol grad)")
    ax.set_ylabel("anomaly F1 (DrivePlotR test)")
    ax.set_ylim(0, 1)
    ax.grid(alpha=0.3)
    ax.legend(fontsize=7, ncol=2)
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)


def _speed_section(speed: dict[str, Any]) -> list[str]:
    lines = [
        f"### Speed: µs per point (DrivePlotR test, {speed['points']} points, one core)",
        "",
        "| method | batch `detect` | streaming `update` |",
        "|---|---|---|",
    ]
    for name, block in speed.items():
        if name == "points":
            continue
        stream = block["stream_us_per_point"]
        lines.append(
            f"| {name} | {block['batch_us_per_point']:.1f} | "
            f"{'-' if stream is None else f'{stream:.1f}'} |"
        )
    return [*lines, ""]


ROBUSTNESS_DETECTOR = "grad-default"
#: Fault draws per robustness cell (the verdicts are seed 0's; the spread says how far
#: one draw moves a cell of one or two test drives).
ROBUSTNESS_DRAWS = 5
R_START, R_END = "<!-- robustness:start -->", "<!-- robustness:end -->"


def robustness_table(args: argparse.Namespace) -> dict[str, Any]:
    """The robustness suite with the shipped model; writes its own block of ``args.markdown``."""
    import shlex

    from gradgps._eval.bench import make_detector
    from gradgps._eval.robustness import robustness_markdown, run_robustness

    report = run_robustness(
        make_detector(ROBUSTNESS_DETECTOR),
        ROBUSTNESS_DETECTOR,
        data_dir=args.data_dir,
        draws=ROBUSTNESS_DRAWS,
    )
    words = ["benchmarks/run_all.py"]
    words += [os.path.relpath(a, REPO) if a.startswith(str(REPO)) else a for a in sys.argv[1:]]
    lines = [R_START, "", "## Robustness: real drives unlike the training data", ""]
    if args.quick:
        lines += ["**quick mode: tiny data, not results**", ""]
    lines += [*robustness_markdown(report, shlex.join(["python", *words])), R_END]
    old = args.markdown.read_text() if args.markdown.is_file() else "# Benchmarks\n\n"
    block = "\n".join(lines) + "\n"
    if R_START in old and R_END in old:
        new = old[: old.index(R_START)] + block + old[old.index(R_END) + len(R_END) + 1 :]
    else:
        new = old.rstrip("\n") + "\n\n" + block
    args.markdown.write_text(new)
    return report


def _lead_summary(grad_reports: dict[str, dict[str, Any]]) -> list[str]:
    out = []
    for title, report in grad_reports.items():
        res = report["results"]
        g = res["grad"]["anomaly"]["f1"]
        base = {m: res[m]["anomaly"]["f1"] for m in BASELINES if m in res}
        best = max(base, key=lambda m: base[m] or 0.0)
        verdict = "at or above" if g is not None and g >= (base[best] or 0.0) else "BELOW"
        out.append(
            f"- {title}: GRAD anomaly F1 {_f(g)} is {verdict} every baseline "
            f"(best baseline: {best}, {_f(base[best])})."
        )
    return out


def write_markdown(
    results: dict[str, Any],
    seconds: dict[str, float],
    path: Path,
    png: str,
    quick: bool,
    command: str,
) -> None:
    lines = [
        START,
        "",
        "## GRAD and the baselines, side by side",
        "",
        f"Generated by `{command}` on {datetime.date.today().isoformat()}"
        + (
            " (the tables not named there are kept from the previous full `make bench`, "
            "with their wall times)"
            if "--tables" in command
            else ""
        )
        + (" (**quick mode: tiny data, not results**)" if quick else "")
        + ".",
        f"Machine: {machine()}; every table in one run, one core (threads pinned to 1).",
        "Wall time per table (s, training of uncached models included): "
        + ", ".join(f"{k} {v:.0f}" for k, v in seconds.items())
        + ".",
        "",
        "Methods (all trained ones on the data set's train split with GRAD's recipe: ten "
        "injection seeds, validation split for early stopping and the threshold, 3-minute "
        "budget): `grad` = GRAD trained on the data set; `grad-default` = the shipped model (the "
        "recipe of docs/model-card.md, not trained on this data set's test split); `rema`, `speed-gate`: statistical, no training; `kf`: "
        "constant-velocity Kalman filter + χ² test (`_baselines/kalman.py`); `cnn`: 1-D CNN "
        "(`_baselines/cnn.py`); `cnn-kf`: CNN then KF + χ² (van Wyk et al., `_baselines/cnn_kf.py`); "
        "`lstm-cnn`: convolutions + LSTM + attention (Javed et al.'s ML-C, `_baselines/lstm_cnn.py`); "
        "`waved` (sensor-grid only): weighted ensemble of `cnn` and `lstm-cnn`, weight and "
        "threshold tuned on validation (after Javed et al.'s WAVED, `_baselines/waved.py`). "
        "Under `sensor-grid` every trained method is trained per row with the same smaller "
        f"recipe ({len(GRID_SEEDS)} injection seeds, {GRID_BUDGET_S:.0f}-second budget, "
        f"patience {GRID_PATIENCE}), and `grad` is the channel GRAD "
        "(`_baselines/channel_grad.py`, docs/deviations.md), thresholded for the best "
        "validation F1 that keeps validation normal recall >= 0.995; `grad-f1` is the same "
        "model thresholded by the baselines' rule (best validation F1, no floor).",
        "",
        "Columns marked **paper** are the numbers printed in the paper, measured on its "
        "own data (MMITSS, Zurich) with its own injection; they are not comparable "
        "number for number with ours and are shown only as reference.",
        "",
    ]
    grad_reports = {}
    for key, title in (("grad-driveplotr", "DrivePlotR"), ("grad-tuc", "TUC")):
        if key in results:
            grad_reports[title] = results[key]
            lines += _grad_section(results[key], title)
    if grad_reports:
        lines += [
            "**paper** (Table 2, GRAD only, percent):",
            "",
            "| data set | normal P | normal R | normal F1 | anomaly P | anomaly R | anomaly F1 |",
            "|---|---|---|---|---|---|---|",
        ]
        for ds, block in PAPER_TABLE2.items():
            lines.append(
                f"| {ds} (paper) | "
                + " | ".join(f"{v:.2f}" for c in ("normal", "anomaly") for v in block[c])
                + " |"
            )
        lines += ["", *_lead_summary(grad_reports), ""]
    verdicts: list[str] = []
    if "sensor-grid" in results:
        table, verdicts = _sensor_section(results["sensor-grid"])
        lines += table
        lines += [
            "`rema` and `speed-gate` look at positions only and flag nothing under "
            "`sensor-grid`, so they have no column there.",
            "",
            "### Does GRAD lead on the sensor grid, row by row (point and window F1)",
            "",
            *[f"- {v}" for v in verdicts],
            "",
        ]
    if "sweep" in results:
        lines += _sweep_section(results["sweep"], png)
    if "speed" in results:
        lines += _speed_section(results["speed"])
        lines += [
            "`rema` has no streaming object of its own (its core streams through "
            "`CorePipeline`), hence no streaming number. Batch = best of 3.",
            "",
        ]
    if verdicts:
        lines += ["", NOTES_FILE.read_text().strip() if NOTES_FILE.is_file() else "", ""]
    lines += [END]
    block = "\n".join(lines) + "\n"
    old = path.read_text() if path.is_file() else "# Benchmarks\n\n"
    if START in old and END in old:
        new = old[: old.index(START)] + block + old[old.index(END) + len(END) + 1 :]
    else:
        new = old.rstrip("\n") + "\n\n" + block
    path.write_text(new)


#: Hand-written explanation of the sensor-grid outcome, kept beside this script.
NOTES_FILE = Path(__file__).with_name("sensor_grid_notes.md")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--quick", action="store_true", help="tiny budget, shipped GRAD model")
    parser.add_argument("--data-dir", default=None, help="data folder (default $GRADGPS_DATA)")
    parser.add_argument("--results", type=Path, default=REPO / "benchmarks" / "results")
    parser.add_argument("--markdown", type=Path, default=REPO / "BENCHMARKS.md")
    parser.add_argument("--table", choices=TABLES, help="run one table in this process (internal)")
    parser.add_argument("--json", type=Path, help="with --table: write its JSON here (internal)")
    parser.add_argument(
        "--tables",
        default=",".join(TABLES),
        help="comma-separated tables to run (default: all); the others are taken from the saved "
        "bench_all JSON, with their wall times",
    )
    parser.add_argument(
        "--render-only",
        action="store_true",
        help="rewrite BENCHMARKS.md from the saved bench_all JSON, run nothing",
    )
    args = parser.parse_args()
    if args.table:
        import torch

        torch.set_num_threads(1)
        report = run_table(args.table, args)
        args.json.write_text(json.dumps(report, indent=1) + "\n")
        return
    suffix = "_quick" if args.quick else ""
    png_name = f"bench_sweep{suffix}.png"
    png = os.path.relpath(args.results / png_name, args.markdown.parent)
    command = "python benchmarks/run_all.py --quick" if args.quick else "make bench"
    chosen = [t.strip() for t in args.tables.split(",") if t.strip()]
    if set(chosen) != set(TABLES):  # a partial run: name it exactly
        command = "python benchmarks/run_all.py" + (" --quick" if args.quick else "")
        command += " --tables " + ",".join(chosen)
    if args.render_only:
        saved = json.loads((args.results / f"bench_all{suffix}.json").read_text())
        write_markdown(saved["results"], saved["seconds"], args.markdown, png, args.quick, command)
        return
    args.results.mkdir(parents=True, exist_ok=True)
    results: dict[str, Any] = {}
    seconds: dict[str, float] = {}
    unknown = [t for t in chosen if t not in TABLES]
    if unknown:
        raise SystemExit(f"unknown tables {unknown}; known: {', '.join(TABLES)}")
    if set(chosen) != set(TABLES):
        saved_file = args.results / f"bench_all{suffix}.json"
        if not saved_file.is_file():
            raise SystemExit(f"--tables needs {saved_file} for the tables not run; run all first")
        saved = json.loads(saved_file.read_text())
        results.update({k: v for k, v in saved["results"].items() if k not in chosen})
        seconds.update({k: v for k, v in saved["seconds"].items() if k not in chosen})
    for table in [t for t in TABLES if t in chosen]:
        stem = f"robustness_{ROBUSTNESS_DETECTOR}" if table == "robustness" else f"bench_{table}"
        target = args.results / f"{stem}{'_quick' if args.quick else ''}.json"
        cmd = [sys.executable, __file__, "--table", table, "--json", str(target)]
        cmd += ["--markdown", str(args.markdown)]
        cmd += ["--quick"] if args.quick else []
        cmd += ["--data-dir", args.data_dir] if args.data_dir else []
        began = time.perf_counter()
        print(f"[bench] {table} ...", flush=True)
        subprocess.run(cmd, check=True)
        seconds[table] = time.perf_counter() - began
        print(f"[bench] {table} done in {seconds[table]:.0f} s", flush=True)
        results[table] = json.loads(target.read_text())
    if "sweep" in chosen:
        _plot_sweep(results["sweep"], args.results / png_name)
    results = {k: results[k] for k in TABLES if k in results}
    seconds = {k: seconds[k] for k in TABLES if k in seconds}
    write_markdown(results, seconds, args.markdown, png, args.quick, command)
    (args.results / f"bench_all{'_quick' if args.quick else ''}.json").write_text(
        json.dumps(
            {
                "seconds": seconds,
                "machine": machine(),
                "date": datetime.date.today().isoformat(),
                "results": results,
            },
            indent=1,
        )
        + "\n"
    )
    print(f"[bench] wrote {args.markdown} and {args.results}", flush=True)
    _peers_table(args)


def _peers_table(args: argparse.Namespace) -> None:
    """The peers section (benchmarks/peers.py, its own markers in BENCHMARKS.md).

    Not in quick mode: tests/test_peers.py runs its own quick mode.
    """
    if args.quick:
        return
    cmd = [sys.executable, str(Path(__file__).with_name("peers.py"))]
    cmd += ["--results", str(args.results), "--markdown", str(args.markdown)]
    cmd += ["--data-dir", args.data_dir] if args.data_dir else []
    print("[bench] peers ...", flush=True)
    subprocess.run(cmd, check=True)


if __name__ == "__main__":
    main()

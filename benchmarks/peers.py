"""The peers table: GRAD next to what users would pick instead; writes its section of BENCHMARKS.md.

    python benchmarks/peers.py [--tune] [--quick] [--dataset NAME ...] [--data-dir DIR]
                               [--results DIR] [--markdown FILE] [--tuned FILE]

One command regenerates the table (``make bench`` runs it too). Every shared
data set :func:`gradgps.load_dataset` knows is used (``--dataset`` narrows it);
a data set without tuned peer settings in ``--tuned`` (default: the committed
``src/gradgps/_baselines/peers_tuned.json``) is tuned first on its validation
split, ``--tune`` re-tunes every one. Protocol and columns: see
``src/gradgps/_eval/peers.py``. GRAD is ``grad-default``, the model shipped in
the package at the time of the run.

BENCHMARKS.md is rewritten only between ``<!-- peers:start -->`` and
``<!-- peers:end -->``. ``--quick`` runs the same code on tiny data with one
grid entry per peer and without ``skmob-filter`` (whose environment takes
minutes to build): the test suite checks the shape of what it writes.
"""

from __future__ import annotations

import os

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS", "NUMBA_NUM_THREADS"):
    os.environ[_var] = "1"

import argparse  # noqa: E402
import datetime  # noqa: E402
import json  # noqa: E402
import sys  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402
from typing import Any  # noqa: E402

from gradgps._eval.robustness import machine  # noqa: E402

REPO = Path(__file__).resolve().parents[1]
START, END = "<!-- peers:start -->", "<!-- peers:end -->"
TITLES = {
    "grad-default": "**gradgps** (`grad-default`, shipped model)",
    "movingpandas-outlier": "movingpandas `OutlierCleaner`",
    "movingpandas-kalman": "movingpandas `KalmanSmootherCV` residual",
    "skmob-filter": "scikit-mobility `filtering.filter`",
    "kalman-chi2": "filterpy Kalman CV + χ² gate",
    "kalman-chi2-vel": "filterpy Kalman CV + χ² gate, reported velocity measured",
    "hampel": "Hampel (rolling median/MAD, east/north)",
    "river-gauss": "river `GaussianScorer`",
    "river-hst": "river `HalfSpaceTrees`",
    "pyod-iforest": "PyOD `IForest`",
}


def _log(msg: str) -> None:
    print(f"[peers] {msg}", file=sys.stderr, flush=True)


def _load() -> str:
    try:
        return "load average {:.1f} / {:.1f} / {:.1f}".format(*os.getloadavg())
    except OSError:
        return "load average unknown"


def run(args: argparse.Namespace) -> dict[str, Any]:
    """Tune what is missing, then score every data set; returns the JSON-ready report."""
    from gradgps import Detector
    from gradgps._baselines.peers import PEER_NAMES, TUNED_FILE
    from gradgps._eval.peers import peer_datasets, peers_table, tune_peers

    peers = [
        p
        for p in (args.peer or PEER_NAMES)
        if not (args.quick and p == "skmob-filter" and not args.peer)
    ]
    tuned_path: Path = args.tuned or TUNED_FILE
    tuned: dict[str, Any] = json.loads(tuned_path.read_text()) if tuned_path.is_file() else {}
    # Without --dataset: the data sets the peers are tuned for (tuning one takes about
    # half an hour here); --tune tunes every one.
    datasets = args.dataset or [d for d in peer_datasets() if args.tune or d in tuned]
    untuned = [d for d in peer_datasets() if d not in datasets]
    if untuned:
        _log(f"peers not tuned for {', '.join(untuned)}: left out (--tune, or --dataset NAME)")
    changed = False
    for ds in datasets:
        have = tuned.get(ds, {})
        todo = [p for p in peers if args.tune or not any(p in v for v in have.values())]
        if todo:
            _log(f"tuning {', '.join(todo)} on {ds}/validation")
            fresh = tune_peers(ds, data_dir=args.data_dir, peers=todo, quick=args.quick, log=_log)
            for variant, settings in fresh.items():
                have.setdefault(variant, {}).update(settings)
            tuned[ds] = have
            changed = True
    if changed:
        tuned_path.parent.mkdir(parents=True, exist_ok=True)
        tuned_path.write_text(json.dumps(tuned, indent=1, sort_keys=True) + "\n")
        _log(f"wrote {tuned_path}")
    tables = {}
    for ds in datasets:
        began = time.perf_counter()
        tables[ds] = peers_table(
            ds, tuned[ds], Detector(), data_dir=args.data_dir, peers=peers, log=_log
        )
        tables[ds]["seconds"] = time.perf_counter() - began
    return {
        "date": datetime.date.today().isoformat(),
        "machine": machine(),
        "load": _load(),
        "quick": args.quick,
        "model": _model_version(),
        "tables": tables,
    }


def _model_version() -> str:
    """The shipped model's identity: its weights' hash and the commit that last changed it."""
    import hashlib
    import subprocess

    from gradgps._grad.detector import _default_model_dir

    folder = _default_model_dir()
    digest = hashlib.sha256((folder / "weights.npz").read_bytes()).hexdigest()[:12]
    done = subprocess.run(
        ["git", "log", "-1", "--format=%h %cs", "--", str(folder)],
        cwd=REPO,
        capture_output=True,
        text=True,
        check=False,
    )
    commit = f", last changed in commit {done.stdout.strip()}" if done.stdout.strip() else ""
    return f"weights.npz sha256 {digest}{commit}"


def _p(value: float | None) -> str:
    return "-" if value is None else f"{value:.3f}"


def _x(value: float | None) -> str:
    return "-" if value is None else f"{value:.2f}×"


def _us(value: float | None) -> str:
    return "-" if value is None else f"{value:.1f}"


def section(report: dict[str, Any], command: str) -> str:
    lines = [
        START,
        "",
        "## The peers: what users would pick instead",
        "",
        f"Generated by `{command}` on {report['date']}"
        + (" (**quick mode: tiny data, not results**)" if report["quick"] else "")
        + f". Machine: {report['machine']}; one process, one thread; {report['load']} at the end "
        "(shared machine: µs figures are noisy).",
        f"GRAD = `grad-default`, the shipped model ({report['model']}).",
        "",
        "Each peer through its own documented API (`src/gradgps/_baselines/peers.py`); its "
        "threshold and one or two settings tuned on the data set's *validation* split by the "
        "committed grid in `src/gradgps/_eval/peers.py` (tuned values in "
        "`src/gradgps/_baselines/peers_tuned.json`); nothing tuned on test. Protocol `grad` "
        "faults, seed 0. **F1 split**: faults injected into the test split alone; **F1 whole**: "
        "injected into the whole file (all splits), then the test rows taken. **clean FA**: "
        "percent of fixes flagged on the untouched test drives. µs per fix: batch `detect` and "
        "streaming `update` (peers with a per-fix form only); ratios are to GRAD on the same "
        "variant. `positions`: only t, lat, lon given; `+speed+heading`: every column the data "
        "has. Peers that do not read speed or heading answer the same in both variants. "
        "scikit-mobility runs in its own environment (`.venv-skmob`, pandas<2); its µs are the "
        "`filter` call alone.",
        "",
    ]
    for ds, table in report["tables"].items():
        for variant, rows in table["variants"].items():
            lines += [
                f"### {ds}, test split ({table['points']} fixes), `{variant}`",
                "",
                "| method | F1 split | F1 whole | F1 / GRAD | clean FA % | batch µs | "
                "stream µs | batch / GRAD |",
                "|---|---|---|---|---|---|---|---|",
            ]
            for name, row in rows.items():
                lines.append(
                    f"| {TITLES.get(name, name)} | {_p(row['split']['f1'])} | "
                    f"{_p(row['whole_file']['f1'])} | {_x(row['f1_ratio_to_grad'])} | "
                    f"{row['clean_false_alarm_pct']:.1f} | {_us(row['batch_us'])} | "
                    f"{_us(row['stream_us'])} | {_x(row['batch_ratio_to_grad'])} |"
                )
            lines.append("")
        lines += [_verdict(ds, table), ""]
    lines.append(END)
    return "\n".join(lines) + "\n"


def _verdict(ds: str, table: dict[str, Any]) -> str:
    parts = []
    for variant, rows in table["variants"].items():
        g = rows["grad-default"]["split"]["f1"] or 0.0
        beat = [
            f"{n} ({_p(r['split']['f1'])})"
            for n, r in rows.items()
            if n != "grad-default" and (r["split"]["f1"] or 0.0) > g
        ]
        parts.append(
            f"`{variant}`: GRAD F1 {g:.3f}, "
            + ("above every peer" if not beat else "below " + ", ".join(beat))
        )
    return f"{ds}: " + "; ".join(parts) + "."


def write_markdown(text: str, path: Path) -> None:
    old = path.read_text() if path.is_file() else "# Benchmarks\n\n"
    if START in old and END in old:
        new = old[: old.index(START)] + text + old[old.index(END) + len(END) + 1 :]
    else:
        new = old.rstrip("\n") + "\n\n" + text
    path.write_text(new)


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--tune", action="store_true", help="re-tune every data set")
    parser.add_argument("--quick", action="store_true", help="shape check: one grid entry")
    parser.add_argument("--dataset", action="append", help="only this data set (repeatable)")
    parser.add_argument("--peer", action="append", help="only this peer (repeatable)")
    parser.add_argument("--data-dir", default=None, help="data folder (default $GRADGPS_DATA)")
    parser.add_argument("--results", type=Path, default=REPO / "benchmarks" / "results")
    parser.add_argument("--markdown", type=Path, default=REPO / "BENCHMARKS.md")
    parser.add_argument("--tuned", type=Path, default=None, help="tuned settings JSON")
    args = parser.parse_args(argv)
    report = run(args)
    args.results.mkdir(parents=True, exist_ok=True)
    out = args.results / f"bench_peers{'_quick' if args.quick else ''}.json"
    out.write_text(json.dumps(report, indent=1) + "\n")
    command = "python benchmarks/peers.py" + (" --tune" if args.tune else "")
    command += " --quick" if args.quick else ""
    write_markdown(section(report, command), args.markdown)
    _log(f"wrote {out} and {args.markdown}")


if __name__ == "__main__":
    main()

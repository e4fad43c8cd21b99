"""The figures of ``eval_bundle.sh`` outputs side by side, one column per bundle.

    python benchmarks/tried/eval_summary.py OUT_A OUT_B ...

Rows: validation anomaly F1 per data set, rate and column variant (and the
positions-only mean), the same over five fault draws (``F1x5``, with normal recall
``NRx5`` and each variant's mean), clean false alarms where they exceed 0.3 %, simulated F1,
protocol ``gnss`` normal recall per data set, false positives and hang-over fixes
summed over the seed pairs per rate (and over the validation drives) with the longest
hang-over run, the first clean fix after a permanent noise or jump run, the ``gnss``
false positives by the episode before them, and DrivePlotR with speed and
heading's missed and false fixes. Reads only the bundles' text files.
"""

from __future__ import annotations

import re
import sys
from pathlib import Path


def table_rows(text: str) -> list[list[str]]:
    """The cells of every markdown table row in ``text`` (the header included, the
    ``|---|`` rule left out), stripped."""
    return [
        [c.strip() for c in line.strip().strip("|").split("|")]
        for line in text.splitlines()
        if line.startswith("|") and not line.startswith("|---")
    ]


def figures(out: Path) -> dict[str, str]:
    got: dict[str, str] = {}
    for variant in ("positions", "speed", "speed_heading"):
        path = out / f"validation_{variant}.txt"
        if not path.exists():
            continue
        f1s = []
        for row in table_rows(path.read_text())[1:]:
            name, columns, rate, _, fa, f1, nr = row[:7]
            got[f"F1 {name} {columns} {rate}"] = f1
            got[f"NR {name} {columns} {rate}"] = nr
            if float(fa.rstrip(" %")) > 0.3:
                got[f"FA {name} {columns} {rate}"] = fa
            if variant == "positions":
                f1s.append(float(f1))
        if f1s:
            got[f"F1 mean {variant}"] = f"{sum(f1s) / len(f1s):.3f}"
    path = out / "draws5.txt"
    if path.exists():
        means: dict[str, list[float]] = {}
        for row in table_rows(path.read_text())[1:]:
            name, columns, rate, _, f1, nr = row[:6]
            got[f"F1x5 {name} {columns} {rate}"] = f1
            got[f"NRx5 {name} {columns} {rate}"] = nr
            means.setdefault(columns, []).append(float(f1))
        for columns, f1s in means.items():
            got[f"F1x5 mean {columns}"] = f"{sum(f1s) / len(f1s):.3f}"
    path = out / "simulated.txt"
    if path.exists():
        for row in table_rows(path.read_text())[1:]:
            got[f"sim F1 {row[0]}"] = row[3]
            got[f"sim FA {row[0]}"] = row[2]
    path = out / "gnss.txt"
    if path.exists():
        for row in table_rows(path.read_text())[1:]:
            got[f"gnss NR {row[0]}"] = row[3]
    sums: dict[str, int] = {}
    for path in sorted(out.glob("hangover*_*.txt")):
        group = "5 pairs" if path.name.startswith("hangover_") else "8 pairs"
        for row in table_rows(path.read_text())[1:]:
            where = "validation" if "validation" in row[0] else row[0]
            for what, value in (("false positives", row[1]), ("hang-over fixes", row[3])):
                key = f"{what} {group} {where}"
                sums[key] = sums.get(key, 0) + int(value)
            key = f"longest hang-over {group} {where}"
            sums[key] = max(sums.get(key, 0), int(row[4].split()[0]))
    got.update({k: str(v) for k, v in sums.items()})
    got.update(ended_figures(out))
    path = out / "variant_errors.txt"
    if path.exists():
        m = re.search(r"missed (\d+) of (\d+) faulty fixes, (\d+) false", path.read_text())
        if m:
            got["DP +speed+heading missed / false"] = f"{m[1]} / {m[3]}"
    return got


def ended_figures(out: Path) -> dict[str, str]:
    """From ``byended.txt``: the first clean fix after a permanent noise / jump run, flagged
    of such endings, simulated and summed over the validation drive sets; from
    ``gnss_after.txt``: the false positives after each kind of ``gnss`` episode, summed."""
    got: dict[str, str] = {}
    path = out / "byended.txt"
    if path.exists():
        sums: dict[str, list[int]] = {}
        where = ""
        for line in path.read_text().splitlines():
            if line.startswith("simulated"):
                where = "simulated 1 Hz"
            elif " validation," in line:
                where = "validation"
            m = re.match(r"(noise|jump) permanent\s+(\d+) of (\d+)", line)
            if m and where:
                key = f"first clean fix flagged after a permanent {m[1]} run, {where}"
                a, b = sums.setdefault(key, [0, 0])
                sums[key] = [a + int(m[2]), b + int(m[3])]
        got.update({k: f"{a} of {b}" for k, (a, b) in sums.items()})
    path = out / "gnss_after.txt"
    if path.exists():
        fps: dict[str, int] = {}
        for row in table_rows(path.read_text())[1:]:
            fps[row[1]] = fps.get(row[1], 0) + int(row[2])
        got.update({f"gnss false positives after {k}": str(v) for k, v in sorted(fps.items())})
    return got


def main() -> None:
    outs = [Path(a) for a in sys.argv[1:]]
    tables = [figures(o) for o in outs]
    keys: list[str] = []
    for t in tables:
        keys += [k for k in t if k not in keys]
    print("| figure | " + " | ".join(o.name for o in outs) + " |")
    print("|---|" + "---|" * len(outs))
    for k in keys:
        print(f"| {k} | " + " | ".join(t.get(k, "-") for t in tables) + " |")


if __name__ == "__main__":
    main()

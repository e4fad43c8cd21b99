"""benchmarks/tried/draws_means.py: means per column variant and paired differences from
fault_age_recall.py tables, models named by their directory's last component."""

from __future__ import annotations

import math

from _script_support import load_script

dm = load_script("benchmarks/tried/draws_means.py")

_TABLE = """models: a, b; fault draws (seeds): [0, 1]

| data set | columns | rate | model | anomaly F1 | normal recall | recall < 30 s |
|---|---|---|---|---|---|---|
| d1 | positions | native | src/gradgps/models/default | 0.900 | 0.990 | 0.9 of 10 |
| d1 | positions | native | /m/cand | 0.950 | 0.995 | 0.9 of 10 |
| d1 | positions | 0.5 Hz | src/gradgps/models/default | 0.800 | 0.990 | - |
| d1 | positions | 0.5 Hz | /m/cand | 0.780 | 0.990 | - |
| d1 | +speed | native | src/gradgps/models/default | 0.970 | 0.999 | - |
| d1 | +speed | native | /m/cand | 0.990 | 0.999 | - |
"""


def test_means_and_paired_differences() -> None:
    cells = dm.read_cells(_TABLE)
    assert set(cells["model"]) == {"default", "cand"}
    means = dm.variant_means(cells)
    assert math.isclose(means.loc["positions", "default"], 0.85)
    assert math.isclose(means.loc["positions", "cand"], 0.865)
    assert math.isclose(means.loc["+speed", "cand"], 0.99)
    by_variant, worst = dm.paired(cells, "default", "cand")
    assert math.isclose(by_variant["positions"], 0.015)
    assert math.isclose(by_variant["+speed"], 0.02)
    assert math.isclose(worst, -0.02)

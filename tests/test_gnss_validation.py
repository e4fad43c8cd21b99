"""benchmarks/tried/gnss_validation.py --draws: one row per data set and model, the
draws' normal recalls in seed order and their mean."""

from __future__ import annotations

from _script_support import load_script

gv = load_script("benchmarks/tried/gnss_validation.py")


def test_draws_table_rows_per_set_and_model() -> None:
    rows = gv.draws_table(
        {
            "default": {"a": [0.9, 1.0], "b": [0.5, 0.5]},
            "cand": {"a": [0.95, 0.96], "b": [1.0, 0.0]},
        }
    )
    assert rows[2:] == [
        "| a | default | 0.900 1.000 | 0.9500 |",
        "| a | cand | 0.950 0.960 | 0.9550 |",
        "| b | default | 0.500 0.500 | 0.5000 |",
        "| b | cand | 1.000 0.000 | 0.5000 |",
    ]

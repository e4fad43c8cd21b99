"""benchmarks/tried/member_losses.py: each member's lowest validation loss and its epoch
come from its own history, and a single network (no members list) is one row."""

from __future__ import annotations

from _script_support import load_script

ml = load_script("benchmarks/tried/member_losses.py")


def _history(val: list[float]) -> list[dict[str, float | int]]:
    return [{"epoch": i + 1, "train_loss": 1.0 / (i + 1), "val_loss": v} for i, v in enumerate(val)]


def test_each_member_reports_its_own_lowest_validation_loss() -> None:
    config = {
        "training": {
            "best_epoch": 2,
            "config": {"seed": 0},
            "history": _history([0.5, 0.4]),
            "members": [
                {"seed": 3, "best_epoch": 2, "history": _history([0.30, 0.20, 0.25])},
                {"seed": 4, "best_epoch": 1, "history": _history([0.10, 0.30])},
            ],
        }
    }
    rows = ml.member_rows(config)
    assert [r["seed"] for r in rows] == [3, 4]
    assert (rows[0]["lowest_val_loss"], rows[0]["lowest_at"]) == (0.20, 2)
    assert (rows[1]["lowest_val_loss"], rows[1]["lowest_at"]) == (0.10, 1)
    assert rows[0]["last_val_loss"] == 0.25
    assert rows[1]["last_train_loss"] == 0.5


def test_a_single_network_is_one_row_with_the_training_seed() -> None:
    config = {
        "training": {"best_epoch": 3, "config": {"seed": 7}, "history": _history([0.3, 0.2, 0.1])}
    }
    (row,) = ml.member_rows(config)
    assert row["seed"] == 7
    assert row["kept_epoch"] == 3
    assert row["lowest_val_loss"] == 0.1

"""Benchmark metrics against hand-worked examples and scikit-learn."""

from __future__ import annotations

import math

import numpy as np
import pytest
from sklearn import metrics as skm

from gradgps import metrics


def test_class_scores_by_hand() -> None:
    # tp=2, fp=1, fn=1, tn=4
    truth = [1, 1, 1, 0, 0, 0, 0, 0]
    pred = [1, 1, 0, 1, 0, 0, 0, 0]
    s = metrics.class_scores(truth, pred)
    assert s["anomaly"] == {"precision": 2 / 3, "recall": 2 / 3, "f1": 2 / 3}
    assert s["normal"]["precision"] == pytest.approx(4 / 5)
    assert s["normal"]["recall"] == pytest.approx(4 / 5)
    assert s["normal"]["f1"] == pytest.approx(0.8)


def test_class_scores_undefined_precision_is_nan_and_f1_follows_scikit_learn() -> None:
    s = metrics.class_scores([0, 1, 0], [0, 0, 0])
    assert math.isnan(s["anomaly"]["precision"])
    assert s["anomaly"]["recall"] == 0.0
    assert s["anomaly"]["f1"] == 0.0
    # Nothing positive at all: F1 0.0, scikit-learn's zero_division default (the one F1).
    assert metrics.class_scores([0, 0], [0, 0])["anomaly"]["f1"] == 0.0


@pytest.mark.parametrize("seed", range(5))
def test_class_scores_match_scikit_learn(seed: int) -> None:
    rng = np.random.default_rng(seed)
    truth = rng.random(500) < 0.15
    pred = np.where(rng.random(500) < 0.7, truth, rng.random(500) < 0.2)
    s = metrics.class_scores(truth, pred)
    for name, label in (("anomaly", 1), ("normal", 0)):
        p, r, f, _ = skm.precision_recall_fscore_support(
            truth, pred, labels=[label], zero_division=np.nan
        )
        assert s[name]["precision"] == pytest.approx(p[0])
        assert s[name]["recall"] == pytest.approx(r[0])
        assert s[name]["f1"] == pytest.approx(f[0])


@pytest.mark.parametrize("seed", range(3))
def test_confusion_matrix_matches_scikit_learn(seed: int) -> None:
    rng = np.random.default_rng(seed)
    labels = ["none", "noise", "jump"]
    truth = rng.choice(labels, 300)
    pred = rng.choice([*labels, "other"], 300)
    ours = metrics.confusion_matrix(truth, pred, labels)
    theirs = skm.confusion_matrix(truth, pred, labels=labels)
    np.testing.assert_array_equal(ours.to_numpy(), theirs)
    assert list(ours.index) == labels


def test_type_accuracy_counts_only_flagged_faults() -> None:
    truth = np.array(["none", "noise", "noise", "jump", "jump"], dtype=object)
    pred = np.array(["jump", "noise", "jump", "jump", "none"], dtype=object)
    flagged = np.array([1, 1, 1, 1, 0])
    assert metrics.type_accuracy(truth, pred, flagged) == pytest.approx(2 / 3)
    assert math.isnan(metrics.type_accuracy(truth, np.full(5, None, dtype=object), flagged))
    assert math.isnan(metrics.type_accuracy(truth, pred, np.zeros(5)))


def test_event_recall_and_delay_by_hand() -> None:
    # Episode 0 at positions 2-4 found at 3 (delay 1); episode 1 bursts at 10,11 and 14,
    # found at 14 (delay 4) though 12 (not its point) is flagged; episode 2 missed.
    episode = np.full(30, -1)
    episode[2:5] = 0
    episode[[10, 11, 14]] = 1
    episode[20:22] = 2
    flagged = np.zeros(30, dtype=bool)
    flagged[[3, 12, 14, 25]] = True
    per = metrics.detection_delays(episode, flagged, np.arange(30))
    assert per["found"].tolist() == [True, True, False]
    assert per["delay"].tolist()[:2] == [1.0, 4.0]
    recall, delay = metrics.event_recall(episode, flagged, np.arange(30))
    assert recall == pytest.approx(2 / 3)
    assert delay == 2.5
    assert all(
        math.isnan(v) for v in metrics.event_recall(np.full(5, -1), np.ones(5), np.arange(5))
    )


def test_false_alarms_per_hour_counts_runs_per_track() -> None:
    # Track a: 1 h, flagged runs [1,2] and [5] -> 2 alarms; track b: 1 h, one run
    # at the very start -> 1 alarm. Rows are shuffled: time order is restored.
    t = np.r_[np.linspace(0, 3600, 10), np.linspace(0, 3600, 4)]
    track = np.r_[np.full(10, "a"), np.full(4, "b")].astype(object)
    flagged = np.zeros(14, dtype=bool)
    flagged[[1, 2, 5, 10]] = True
    order = np.random.default_rng(0).permutation(14)
    assert metrics.false_alarms_per_hour(flagged[order], track[order], t[order]) == pytest.approx(
        1.5
    )


def test_rmse_m_by_hand() -> None:
    lat_true = np.zeros(3)
    lon_true = np.zeros(3)
    metre = 1.0 / 111195.08  # degrees of latitude per metre on the mean sphere
    lat = np.array([3 * metre, 4 * metre, 100.0 * metre])
    rmse = metrics.rmse_m(lat, lon_true, lat_true, lon_true, mask=[True, True, False])
    assert rmse == pytest.approx(math.sqrt((9 + 16) / 2), rel=1e-4)
    assert math.isnan(metrics.rmse_m(lat, lon_true, lat_true, lon_true, mask=[False] * 3))


@pytest.mark.parametrize(
    ("truth", "pred"),
    [
        ([], []),
        ([0, 0, 0], [0, 0, 0]),
        ([1, 0, 1, 1], [1, 0, 0, 1]),
        ([0, 0], [1, 1]),
        ([1, 1], [0, 0]),
        ([1, 0, 1, 0, 1], [1, 1, 0, 0, 1]),
    ],
)
def test_one_f1_with_the_scikit_learn_convention(truth: list[int], pred: list[int]) -> None:
    """Every F1 in gradgps (training, tuning, metrics) is this one, equal to scikit-learn's."""
    from sklearn.metrics import f1_score as sk_f1

    from gradgps._result import f1_score
    from gradgps._train.tune_rema import f1_scores

    expected = float(sk_f1(truth, pred, zero_division=0.0)) if truth else 0.0
    assert f1_score(truth, pred) == pytest.approx(expected)
    assert f1_scores(pred, truth)[0] == pytest.approx(expected)
    assert metrics.class_scores(truth, pred)["anomaly"]["f1"] == pytest.approx(expected)

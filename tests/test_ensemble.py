"""Several GRAD networks shipped as one: the merged network is exactly their mean."""

from __future__ import annotations

import numpy as np
import pytest

torch = pytest.importorskip("torch")

from gradgps._exceptions import ConfigError  # noqa: E402
from gradgps._grad.gru import GRUModel, diagonal_blocks  # noqa: E402
from gradgps._grad.model_io import export_torch  # noqa: E402
from gradgps._train.torch_gru import (  # noqa: E402
    GRADNet,
    TrainConfig,
    merge_networks,
    network_from_arrays,
    train_ensemble,
)


def _nets(k: int, n_features: int = 7, n_bias: int = 4, confirm: bool = False) -> list[GRADNet]:
    nets = []
    for seed in range(k):
        torch.manual_seed(seed)
        net = GRADNet(n_features, n_bias, 5, 3, confirm_head=confirm)
        net.scaler_mean.copy_(torch.linspace(-1, 1, n_features))
        net.scaler_std.copy_(torch.linspace(0.5, 2, n_features))
        nets.append(net)
    return nets


@pytest.mark.parametrize("k", [2, 3, 4])
def test_the_kernel_multiplies_only_the_members_blocks_and_gives_the_same_bits(k: int) -> None:
    """A merged network's recurrent and second-layer input weights are block-diagonal:
    the kernel finds the k members and multiplies only their blocks, and every output
    equals, bit for bit, the same kernel's dense products (told there is one block)."""
    merged = merge_networks(_nets(k, confirm=True))
    weights = export_torch(merged)
    assert diagonal_blocks(weights) == k
    mean = merged.scaler_mean.numpy().astype(np.float64)
    std = merged.scaler_std.numpy().astype(np.float64)
    model = GRUModel(weights, mean, std, mode="stream")
    assert model.dims[5] == k
    feats = np.random.default_rng(k).normal(0, 2, (60, 7))
    blocks = model.predict(feats)
    model.dims[5] = 1
    dense = model.predict(feats)
    np.testing.assert_array_equal(blocks.anomaly, dense.anomaly)
    np.testing.assert_array_equal(blocks.bias, dense.bias)
    assert blocks.confirm is not None
    assert dense.confirm is not None
    np.testing.assert_array_equal(blocks.confirm, dense.confirm)


def test_one_nonzero_off_the_blocks_makes_the_weights_dense() -> None:
    """Only exact zeros are skipped: one off-block weight, and the blocks are not used."""
    weights = export_torch(merge_networks(_nets(2)))
    assert diagonal_blocks(weights) == 2
    w = np.array(weights["gru2.weight_hh"])
    w[0, -1] = 1e-30  # unit 0 of member 0 reading member 1's last unit
    assert diagonal_blocks({**weights, "gru2.weight_hh": w}) == 1
    assert diagonal_blocks(export_torch(_nets(1)[0])) == 1


@pytest.mark.parametrize("k", [1, 2, 3])
def test_merged_logits_are_the_members_mean(k: int) -> None:
    nets = _nets(k)
    merged = merge_networks(nets)
    assert (merged.gru1.hidden_size, merged.gru2.hidden_size) == (5 * k, 3 * k)
    x = torch.randn(4, 30, 7) * 3
    with torch.no_grad():
        got_a, got_b, _ = merged(x)
        want_a = torch.stack([net(x)[0] for net in nets]).mean(0)
        want_b = torch.stack([net(x)[1] for net in nets]).mean(0)
    torch.testing.assert_close(got_a, want_a, rtol=1e-5, atol=1e-5)
    torch.testing.assert_close(got_b, want_b, rtol=1e-5, atol=1e-5)


def test_the_detector_kernel_runs_a_merged_network_as_torch_does() -> None:
    """No inference code knows about ensembles: the numba GRU on the merged weights
    gives the merged torch network's probabilities."""
    nets = _nets(3)
    merged = merge_networks(nets)
    feats = np.random.default_rng(0).normal(0, 2, (50, 7))
    model = GRUModel(
        export_torch(merged),
        merged.scaler_mean.numpy().astype(np.float64),
        merged.scaler_std.numpy().astype(np.float64),
        mode="stream",
    )
    with torch.no_grad():
        la, _, _ = merged(torch.from_numpy(feats.astype(np.float32))[None])
    want = torch.softmax(la[0], -1)[:, 1].numpy()
    np.testing.assert_allclose(model.predict(feats).anomaly, want, rtol=1e-4, atol=1e-5)


@pytest.mark.parametrize("k", [1, 2, 3])
def test_merged_confirm_head_is_the_members_mean(k: int) -> None:
    nets = _nets(k, confirm=True)
    merged = merge_networks(nets)
    x = torch.randn(3, 25, 7) * 3
    with torch.no_grad():
        got = merged.run(x)
        outs = [net.run(x) for net in nets]
    assert got.confirm is not None
    torch.testing.assert_close(
        got.confirm, torch.stack([o.confirm for o in outs]).mean(0), rtol=1e-5, atol=1e-5
    )
    torch.testing.assert_close(
        got.anomaly, torch.stack([o.anomaly for o in outs]).mean(0), rtol=1e-5, atol=1e-5
    )


def test_members_must_share_architecture_and_scaler() -> None:
    a, b = _nets(2)
    b.scaler_mean.add_(1.0)
    with pytest.raises(ConfigError, match="scaler"):
        merge_networks([a, b])
    with pytest.raises(ConfigError, match="architecture"):
        merge_networks([a, GRADNet(7, 4, 6, 3)])
    with pytest.raises(ConfigError, match="architecture"):
        merge_networks([_nets(1)[0], _nets(1, confirm=True)[0]])
    with pytest.raises(ConfigError):
        merge_networks([])


def _sequences(n: int, seed: int) -> list[tuple[np.ndarray, np.ndarray, np.ndarray]]:
    rng = np.random.default_rng(seed)
    out = []
    for _ in range(n):
        x = rng.normal(0, 1, (60, 5)).astype(np.float32)
        y = (rng.random(60) < 0.2).astype(np.int64)
        x[y == 1] += 3.0
        out.append((x, y, y.copy()))
    return out


def _tiny_config(**changes: object) -> TrainConfig:
    """Two tiny stream members' worth of training: seconds."""
    base: dict[str, object] = {
        "bias_classes": ("none", "noise"),
        "mode": "stream",
        "hidden1": 4,
        "hidden2": 3,
        "max_epochs": 2,
        "batch_size": 4,
        "chunk_length": 20,
        "progress": False,
        "seed": 5,
    }
    return TrainConfig(**{**base, **changes})  # type: ignore[arg-type]


def test_an_ensemble_is_its_members_as_trained_alone_merged() -> None:
    """Member k is the network train_model gives for seed + k (nothing shared but the
    data), the merged network is merge_networks of them, and its record names each."""
    from gradgps._train.torch_gru import train_model

    config = _tiny_config()
    train, val = _sequences(8, 0), _sequences(3, 1)
    ensemble = train_ensemble(train, val, config, 2)
    alone = train_model(train, val, TrainConfig(**{**config.__dict__, "seed": 6}))
    for name, value in export_torch(alone.network).items():
        np.testing.assert_array_equal(export_torch(ensemble.members[1].network)[name], value)
    merged = merge_networks([m.network for m in ensemble.members])
    for name, value in export_torch(merged).items():
        np.testing.assert_array_equal(export_torch(ensemble.network)[name], value)
    cfg = ensemble.model_config([f"f{i}" for i in range(5)], {}, {})
    assert cfg["architecture"]["hidden1"] == 8
    assert cfg["architecture"]["hidden2"] == 6
    assert [m["seed"] for m in cfg["training"]["members"]] == [5, 6]
    # the members' mean threshold
    assert ensemble.anomaly_threshold == pytest.approx(
        (ensemble.members[0].anomaly_threshold + ensemble.members[1].anomaly_threshold) / 2
    )
    with pytest.raises(ConfigError):
        train_ensemble(train, val, config, 0)


def test_members_trained_in_parallel_are_the_members_trained_one_by_one() -> None:
    """``jobs=2`` trains the members in two spawned processes: the same weights bit for
    bit, the same thresholds, in order (make default-model relies on it)."""
    config = _tiny_config(confirm_head=True)
    train, val = _sequences(8, 0), _sequences(3, 1)
    serial = train_ensemble(train, val, config, 3)
    parallel = train_ensemble(train, val, config, 3, jobs=2)
    for name, value in export_torch(serial.network).items():
        np.testing.assert_array_equal(export_torch(parallel.network)[name], value)
    assert parallel.anomaly_threshold == serial.anomaly_threshold
    assert parallel.confirm_threshold == serial.confirm_threshold
    assert [m.config.seed for m in parallel.members] == [5, 6, 7]
    with pytest.raises(ConfigError, match="jobs"):
        train_ensemble(train, val, config, 2, jobs=0)


def test_an_ensemble_with_confirm_heads_keeps_the_members_mean_confirm_threshold() -> None:
    config = _tiny_config(confirm_head=True)
    ensemble = train_ensemble(_sequences(8, 0), _sequences(3, 1), config, 2)
    members = [m.confirm_threshold for m in ensemble.members]
    assert all(t is not None for t in members)
    assert ensemble.confirm_threshold == pytest.approx(sum(members) / 2)  # type: ignore[arg-type]
    cfg = ensemble.model_config([f"f{i}" for i in range(5)], {}, {})
    assert cfg["thresholds"]["confirm"] == ensemble.confirm_threshold
    assert [m["confirm_threshold"] for m in cfg["training"]["members"]] == members
    assert ensemble.network.confirm_head is not None


def test_merge_members_script_equals_one_merge_of_the_members(tmp_path) -> None:
    """benchmarks/merge_members.py reads model directories back into networks exactly and
    merges them as train_ensemble does; a merge of two merged pairs is the four members'
    mean (the same logits, units in another order)."""
    import subprocess
    import sys
    from pathlib import Path

    from _gru_support import model_config, random_weights
    from gradgps._grad.model_io import gru_model, load_model, save_model

    script = Path(__file__).resolve().parents[1] / "benchmarks" / "merge_members.py"
    dirs = []
    for seed in range(4):
        config = model_config(7, 4)
        config["architecture"]["confirm_head"] = True
        config["thresholds"] = {"anomaly": 0.5 + 0.1 * seed, "confirm": 0.4 + 0.1 * seed}
        save_model(
            tmp_path / f"m{seed}", random_weights(7, 4, seed=seed, confirm_head=True), config
        )
        dirs.append(tmp_path / f"m{seed}")

    def merge(out: Path, *members: Path) -> Path:
        subprocess.run([sys.executable, str(script), str(out), *map(str, members)], check=True)
        return out

    pairs = [merge(tmp_path / "a", *dirs[:2]), merge(tmp_path / "b", *dirs[2:])]
    four = gru_model(*load_model(merge(tmp_path / "four", *pairs)))
    _, cfg = load_model(tmp_path / "four")
    assert cfg["thresholds"] == {"anomaly": pytest.approx(0.65), "confirm": pytest.approx(0.55)}
    features = np.random.default_rng(0).normal(0, 2, (40, 7))
    logits = []
    for d in dirs:
        w, c = load_model(d)
        net = network_from_arrays(w, c["scaler"]["mean"], c["scaler"]["std"])
        with torch.no_grad():
            logits.append(net.run(torch.from_numpy(features.astype(np.float32))[None]))
    mean_confirm = torch.stack([o.confirm for o in logits]).mean(0)
    want = torch.softmax(mean_confirm[0], -1)[:, 1].numpy()
    np.testing.assert_allclose(four.predict(features).confirm, want, atol=1e-5)

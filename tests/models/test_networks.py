"""Model shapes, attention normalisation, convex temporal mixture, parameter counts, registry errors."""

import numpy as np
import pytest
import torch

from irlsim.bench.synthetic import default_theta_true, make_split
from irlsim.errors import IrlsimError
from irlsim.models import (
    MODEL_NAMES,
    STAGE1_MODELS,
    FeatureStats,
    ModelConfig,
    build_model,
    compute_feature_stats,
    count_parameters,
)

B, N, K = 3, 64, 10
CFG = ModelConfig(
    hidden_channels=8,
    latent=8,
    attention_hidden=4,
    head_hidden=16,
    fc_hidden=16,
    lstm_hidden=8,
    tan_fc_hidden=8,
    history=5,
)


def _batch():
    g = torch.Generator().manual_seed(0)
    return (
        torch.rand(B, N, 15, generator=g),
        torch.randn(B, N, K, 3, generator=g),
        torch.randn(B, N, K, 2, generator=g),
    )


@pytest.mark.parametrize("name", STAGE1_MODELS)
def test_stage1_shapes_and_non_negative_theta(name):
    torch.manual_seed(0)
    model = build_model(name, CFG, N, None)
    out = model(*_batch())
    assert out["theta"].shape == (B, 15) and (out["theta"] >= 0).all()
    if name.startswith("PACNN"):
        assert out["context"].shape == (B, CFG.latent)
        assert out["attention"].shape == (B, N)
        torch.testing.assert_close(out["attention"].sum(-1), torch.ones(B))
        assert out["attention_pooled"].shape == (B, N // CFG.pool)
    else:
        assert "attention" not in out


def test_pacnn_handles_n_not_divisible_by_pool():
    model = build_model("PACNN", CFG, 61, None)
    f, c, a = (x[:, :61] for x in _batch())
    out = model(f, c, a)
    assert out["attention"].shape == (B, 61) and out["attention_pooled"].shape == (B, 8)
    torch.testing.assert_close(out["attention"].sum(-1), torch.ones(B))


def test_forward_asserts_shapes():
    model = build_model("PACNN", CFG, N, None)
    f, c, a = _batch()
    with pytest.raises(AssertionError):
        model(f, c[:, :, :5], a)


@pytest.mark.parametrize("name", ["PTACNN", "PTACNN+S"])
def test_ptacnn_output_is_a_convex_combination_of_the_history(name):
    torch.manual_seed(0)
    model = build_model(name, CFG, N, None)
    thetas = torch.rand(B, CFG.history, 15)
    out = model(torch.randn(B, CFG.history, CFG.latent), thetas)
    w = out["weights"]
    assert w.shape == (B, CFG.history) and (w >= 0).all()
    torch.testing.assert_close(w.sum(-1), torch.ones(B))
    torch.testing.assert_close(out["theta"], (w.unsqueeze(-1) * thetas).sum(1))
    assert (out["theta"] <= thetas.max(1).values + 1e-6).all()
    assert (out["theta"] >= thetas.min(1).values - 1e-6).all()


def test_parameter_counts():
    assert count_parameters(build_model("LIRL", CFG, N, None)) == 15
    small = count_parameters(build_model("1DCNN", CFG, 64, None))
    large = count_parameters(build_model("1DCNN", CFG, 128, None))
    assert large > small  # the 1DCNN head sees every pooled policy
    assert count_parameters(build_model("PACNN", CFG, 64, None)) == count_parameters(
        build_model("PACNN", CFG, 128, None)
    )


def test_unknown_model_name_lists_the_known_ones():
    with pytest.raises(IrlsimError, match="PTACNN\\+S"):
        build_model("PACN", CFG, N, None)


def test_theta_is_in_raw_units_via_the_stored_scale():
    split = make_split(8, N, default_theta_true(), seed=0)
    stats = compute_feature_stats(split, chunk=3)
    assert isinstance(stats, FeatureStats) and stats.k == K
    flat = np.concatenate([split.features.reshape(-1, 15)], 1)
    np.testing.assert_allclose(stats.mean[:15], flat.mean(0), rtol=1e-5)
    torch.manual_seed(0)
    model = build_model("LIRL", CFG, N, stats)
    theta = model(*_batch())["theta"][0]
    expected = torch.nn.functional.softplus(torch.zeros(15)) / torch.as_tensor(stats.std[:15]).float()
    torch.testing.assert_close(theta, expected)
    assert set(MODEL_NAMES) >= {"LIRL", "PTACNN"}


@pytest.mark.parametrize("name", ["1DCNN", "Bi1DCNN", "PACNN"])
def test_bounded_theta_stays_within_the_factor_of_the_learned_base(name):
    """theta_bound B: theta_n = softplus(b) * B^tanh(out); whatever the head outputs, each weight lies
    within a factor B of softplus(b) (closed form at out = 0 and at saturation)."""
    import dataclasses

    torch.manual_seed(0)
    model = build_model(name, dataclasses.replace(CFG, theta_bound=4.0), N, None)
    base = torch.nn.functional.softplus(model.theta_base.detach())
    torch.testing.assert_close(model.to_theta(torch.zeros(2, 15)), base.expand(2, 15))
    huge = model.to_theta(torch.tensor([[1e3] * 15, [-1e3] * 15]))
    torch.testing.assert_close(huge, torch.stack([base * 4.0, base / 4.0]))
    theta = model(*_batch())["theta"]
    assert ((theta >= base / 4.0 - 1e-6) & (theta <= base * 4.0 + 1e-6)).all()
    theta.sum().backward()
    assert model.theta_base.grad is not None and model.theta_base.grad.abs().sum() > 0
    unbounded = build_model(name, CFG, N, None)
    assert not hasattr(unbounded, "theta_base")


@pytest.mark.parametrize("bound", [0.5, 1.0, -2.0])
def test_theta_bound_must_be_zero_or_above_one(bound):
    with pytest.raises(IrlsimError, match="theta_bound"):
        ModelConfig(theta_bound=bound).validate()

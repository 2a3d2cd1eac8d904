"""Max-ent IRL objective and metrics: gradient (Eq. 3), hand-computed metrics, recovery of a known theta."""

import numpy as np
import torch

from irlsim.bench.synthetic import make_split
from irlsim.irl.objectives import (
    attention_loss,
    attention_target,
    cycle_metrics,
    demo_distance,
    evaluate_thetas,
    expected_distance,
    expected_value_difference,
    history_indices,
    history_mean,
    nll,
    optimal_policy_distance,
    summarize,
)

torch.manual_seed(0)


def test_log_likelihood_gradient_is_papers_eq3():
    """d(-NLL)/d theta = E_p[f] - f^D (the paper's Eq. 3), i.e. d NLL / d theta = f^D - E_p[f]."""
    f = torch.rand(4, 7, 15, dtype=torch.float64) * 3
    theta = (torch.rand(4, 15, dtype=torch.float64) * 2).requires_grad_()
    demo = torch.tensor([0, 3, 6, 2])
    (-nll(theta, f, demo)).sum().backward()
    p = torch.softmax(-(f @ theta.detach().unsqueeze(-1)).squeeze(-1), dim=-1)
    expected = (p.unsqueeze(-1) * f).sum(1) - f[torch.arange(4), demo]
    torch.testing.assert_close(theta.grad, expected)


def test_nll_is_stable_for_huge_theta():
    f = torch.rand(2, 5, 15) * 100
    out = nll(torch.full((2, 15), 1e4), f, torch.tensor([0, 1]))
    assert torch.isfinite(out).all() and (out >= 0).all()


def _three_policy_case():
    # theta = e_0, so V = -f_0; f_0 = (0, ln 2, ln 4) -> p proportional to (1, 1/2, 1/4) = (4, 2, 1) / 7
    f = torch.zeros(1, 3, 15, dtype=torch.float64)
    f[0, :, 0] = torch.tensor([0.0, np.log(2), np.log(4)])
    theta = torch.zeros(1, 15, dtype=torch.float64)
    theta[0, 0] = 1.0
    d = torch.tensor([[0.3, 0.1, 0.5]], dtype=torch.float64)
    return theta, f, d, torch.tensor([1])


def test_metrics_on_a_hand_computed_three_policy_case():
    theta, f, d, demo = _three_policy_case()
    p = np.array([4, 2, 1]) / 7
    v = -np.array([0.0, np.log(2), np.log(4)])
    assert np.isclose(nll(theta, f, demo).item(), -np.log(2 / 7))
    assert np.isclose(expected_value_difference(theta, f, demo).item(), abs(p @ v - v[1]) / abs(v[1]))
    assert np.isclose(expected_distance(theta, f, d).item(), p @ [0.3, 0.1, 0.5])
    assert np.isclose(optimal_policy_distance(theta, f, d).item(), 0.3)  # argmax V is policy 0
    assert np.isclose(demo_distance(d, demo).item(), 0.1)
    m = cycle_metrics(theta, f, d, demo)
    assert np.isclose(m["evd"].item(), abs(p @ v - v[1]) / abs(v[1]))
    assert np.isclose(m["nll"].item(), -np.log(2 / 7))


def test_cycles_without_demonstration_are_nan_and_skipped():
    theta, f, d, _ = _three_policy_case()
    m = cycle_metrics(theta.repeat(2, 1), f.repeat(2, 1, 1), d.repeat(2, 1), torch.tensor([1, -1]))
    assert torch.isnan(m["nll"][1]) and torch.isnan(m["evd"][1]) and torch.isnan(m["demo"][1])
    split = type(
        "S",
        (),
        {
            "features": f.repeat(2, 1, 1).numpy(),
            "distances": d.repeat(2, 1).numpy(),
            "demo_index": np.array([1, -1]),
        },
    )
    s = summarize(evaluate_thetas(theta.repeat(2, 1).numpy(), split, chunk=1))
    assert np.isclose(s["opd"], 0.3) and np.isclose(s["demo"], 0.1)


def test_history_mean_stays_inside_episodes():
    thetas = np.arange(7, dtype=np.float32)[:, None].repeat(15, 1)
    episode = np.array([0, 0, 0, 0, 1, 1, 1])
    out = history_mean(thetas, episode, H=3)[:, 0]
    np.testing.assert_allclose(out, [0, 0.5, 1, 2, 4, 4.5, 5])
    idx = history_indices(episode, H=3)
    np.testing.assert_array_equal(idx[0], [0, 0, 0])
    np.testing.assert_array_equal(idx[3], [1, 2, 3])
    np.testing.assert_array_equal(idx[5], [4, 4, 5])


def test_attention_target_is_a_pooled_distribution():
    d = torch.rand(3, 20)
    t = attention_target(d, pool=8, tau=0.5)
    assert t.shape == (3, 3)
    torch.testing.assert_close(t.sum(-1), torch.ones(3))
    assert torch.allclose(attention_loss(t, t), torch.zeros(3))


def test_linear_irl_recovers_a_known_theta():
    theta_true = np.linspace(0.2, 2.0, 15)[np.random.default_rng(3).permutation(15)]
    s = make_split(400, 40, theta_true, seed=5)
    f, demo = torch.as_tensor(s.features, dtype=torch.float64), torch.as_tensor(s.demo_index)
    w = torch.zeros(15, dtype=torch.float64, requires_grad=True)
    opt = torch.optim.LBFGS([w], max_iter=200, line_search_fn="strong_wolfe")

    def closure():
        opt.zero_grad()
        loss = nll(w.expand(len(demo), 15), f, demo).mean()
        loss.backward()
        return loss

    opt.step(closure)
    est = w.detach().numpy()
    cos = est @ theta_true / np.linalg.norm(est) / np.linalg.norm(theta_true)
    assert cos >= 0.95, cos

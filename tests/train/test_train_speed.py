"""The training-throughput options of stage 1 on a tiny real dataset (SUMO, the expert's demonstrations):
the policy-major encoder layout, the cosine schedule, the fast config's reproducibility, warm starts and
their refusals, and the sampled max-ent normaliser. Timings are never asserted (irlsim bench measures)."""

import dataclasses
import math

import numpy as np
import pytest
import torch

from irlsim import devices
from irlsim.config import load_config, to_dict
from irlsim.errors import IrlsimError
from irlsim.irl.objectives import nll, sampled_nll
from irlsim.train import Stage1Config, load_model, train_stage1
from irlsim.train.batching import gather_batch, get_split, predict_split
from irlsim.train.loop import scheduled_lr

FAST = "configs/train/stage1_fast.toml"


@pytest.fixture(scope="module")
def data(tiny_dataset):
    from irlsim.data.reader import open_dataset

    return open_dataset(tiny_dataset)


def _smoke(**kw):
    return dataclasses.replace(Stage1Config.smoke(), **{"models": ("PACNN+S",), **kw})


def test_new_options_are_stored_only_when_set():
    """The default config's stored form (checkpoints, summary.json) is what it was before the options
    existed, so default runs keep their bytes; a set option is recorded."""
    plain = to_dict(Stage1Config())
    assert not {"encoder_layout", "lr_schedule", "init_from"} & set(plain)
    fast = to_dict(load_config(Stage1Config, FAST, {"lr_schedule": "cosine"}))
    assert fast["lr_schedule"] == "cosine" and fast["threads"] == 1
    assert "init_from" not in fast and "encoder_layout" not in fast
    assert set(to_dict(Stage1Config(), all_fields=True)) >= {"encoder_layout", "lr_schedule", "init_from"}


@pytest.mark.parametrize(
    "key, value, words",
    [
        ("encoder_layout", "nhwc", "encoder_layout must be one of"),
        ("lr_schedule", "step", "lr_schedule must"),
    ],
)
def test_bad_options_are_refused_in_one_line(key, value, words):
    with pytest.raises(IrlsimError, match=words) as e:
        load_config(Stage1Config, FAST, {key: value})
    assert "\n" not in str(e.value)


def test_cosine_schedule():
    cfg = Stage1Config(lr=1e-2, epochs=4, lr_schedule="cosine")
    assert scheduled_lr(cfg, 0, 10) == pytest.approx(1e-2)
    assert scheduled_lr(cfg, 20, 10) == pytest.approx(5e-3)
    assert scheduled_lr(cfg, 40, 10) == pytest.approx(0.0, abs=1e-12)
    lrs = [scheduled_lr(cfg, s, 10) for s in range(40)]
    assert all(a > b for a, b in zip(lrs, lrs[1:], strict=False))
    assert scheduled_lr(dataclasses.replace(cfg, lr_schedule="constant"), 33, 10) == 1e-2


def test_fast_config_same_seed_same_bytes(data, tmp_path):
    """The fast config (and the measured levers on top of it) give the same bytes from the same seed."""
    over = {"models": ["PACNN+S"], "epochs": 2, "tensorboard": False, "validate_every": 1}
    for levers in ({}, {"lr_schedule": "cosine", "encoder_layout": "channels_last", "batch_size": 16}):
        cfg = load_config(Stage1Config, FAST, {**over, **levers})
        for run in ("a", "b"):
            train_stage1(data, cfg, tmp_path / str(len(levers)) / run)
        a = (tmp_path / str(len(levers)) / "a" / "PACNN+S" / "checkpoint.pt").read_bytes()
        assert a == (tmp_path / str(len(levers)) / "b" / "PACNN+S" / "checkpoint.pt").read_bytes()
    ckpt = torch.load(tmp_path / "3" / "a" / "PACNN+S" / "checkpoint.pt", weights_only=True)
    assert ckpt["config"]["encoder_layout"] == "channels_last" and ckpt["provenance"]["threads"] == 1
    # the schedule ran: the last step's learning rate is the cosine's, below the configured one
    rows = int((np.asarray(get_split(data, "train", True, True).demo_index) >= 0).sum())
    steps = -(-rows // cfg.batch_size)
    last = ckpt["optimizer"]["param_groups"][0]["lr"]
    assert last == pytest.approx(scheduled_lr(cfg, 2 * steps - 1, steps)) and last < cfg.lr
    assert all(math.isfinite(r["val/opd"]) for r in ckpt["metrics"])


def test_channels_last_gives_the_conv_paths_loss_and_gradients(data):
    """Both layouts on a real mini-batch, same weights: the same loss and gradients up to float rounding
    (Adam magnifies rounding in near-zero gradients, so trained weights are not compared)."""
    from irlsim.irl.objectives import attention_loss, attention_target, cycle_metrics
    from irlsim.models.networks import set_encoder_layout
    from irlsim.models.normalization import compute_feature_stats
    from irlsim.models.registry import build_model

    split = get_split(data, "train")
    mb = _batch(data, 16)
    torch.manual_seed(0)
    model = build_model(
        "PACNN+S", Stage1Config().model, split.features.shape[1], compute_feature_stats(split)
    )
    grads = {}
    for layout in ("channels_first", "channels_last"):
        set_encoder_layout(model, layout)
        model.zero_grad()
        out = model(mb["features"], mb["control_points"], mb["actions"])
        loss = cycle_metrics(out["theta"], mb["features"], mb["distances"], mb["demo_index"])["nll"].mean()
        target = attention_target(mb["distances"], model.pool, 0.5)
        (loss + attention_loss(out["attention_pooled"], target).mean()).backward()
        grads[layout] = (loss.detach(), {k: p.grad.clone() for k, p in model.named_parameters()})
    (la, ga), (lb, gb) = grads["channels_first"], grads["channels_last"]
    assert torch.allclose(la, lb, rtol=1e-5)
    # tolerance relative to the largest gradient: some are 0 analytically (the attention logits' bias,
    # a softmax shift) and rounding noise in both
    scale = max(float(g.abs().max()) for g in ga.values())
    for k in ga:
        assert torch.allclose(ga[k], gb[k], rtol=1e-3, atol=1e-5 * scale), k


def test_channels_last_trains(data, tmp_path):
    summary = train_stage1(data, _smoke(epochs=2, encoder_layout="channels_last"), tmp_path)["PACNN+S"]
    rows = torch.load(summary["checkpoint"], weights_only=True)["metrics"]
    assert rows[-1]["train/nll"] < rows[0]["train/nll"] and math.isfinite(rows[-1]["val/opd"])


def test_warm_start_continues_the_checkpoint(data, tmp_path):
    first = train_stage1(data, _smoke(epochs=2), tmp_path / "r0")["PACNN+S"]
    source = load_model(first["checkpoint"])
    cfg = _smoke(epochs=0, init_from=first["checkpoint"])
    summary = train_stage1(data, cfg, tmp_path / "r1")["PACNN+S"]
    warm = load_model(summary["checkpoint"])
    # the untrained (epochs = 0) warm start is the source's inference network, normalisation included
    val = get_split(data, "validation")
    assert np.array_equal(predict_split(source.model, val)["theta"], predict_split(warm.model, val)["theta"])
    record = warm.checkpoint["warm_start"]
    assert record["path"] == first["checkpoint"] and record["model"] == "PACNN+S"
    assert record["epoch"] == source.checkpoint["best"]["epoch"] and summary["warm_start"] == record
    assert warm.checkpoint["config"]["init_from"] == first["checkpoint"]
    assert warm.checkpoint["feature_stats"] == source.checkpoint["feature_stats"]
    # fine-tuning from it trains, and a resume keeps the record
    train_stage1(data, dataclasses.replace(cfg, epochs=1), tmp_path / "r1")
    tuned = torch.load(tmp_path / "r1" / "PACNN+S" / "checkpoint.pt", weights_only=True)
    assert tuned["epoch"] == 1 and tuned["warm_start"] == record


def test_warm_start_refusals(data, tmp_path):
    lirl = train_stage1(data, _smoke(models=("LIRL",), epochs=1), tmp_path / "lirl")["LIRL"]["checkpoint"]
    with pytest.raises(IrlsimError, match="holds the stage-1 LIRL, not the stage-1 PACNN\\+S") as e:
        train_stage1(data, _smoke(epochs=1, init_from=lirl), tmp_path / "a")
    assert "\n" not in str(e.value)
    pacnn = train_stage1(data, _smoke(epochs=1), tmp_path / "p")["PACNN+S"]["checkpoint"]
    bigger = dataclasses.replace(Stage1Config.smoke().model, latent=12)
    with pytest.raises(IrlsimError, match="other network sizes \\(latent 8 vs 12\\)"):
        train_stage1(data, _smoke(epochs=1, init_from=pacnn, model=bigger), tmp_path / "b")
    with pytest.raises(IrlsimError, match="not found"):
        train_stage1(data, _smoke(epochs=1, init_from=str(tmp_path / "none.pt")), tmp_path / "c")
    assert not (tmp_path / "a" / "PACNN+S" / "checkpoint.pt").exists()


def _batch(data, n=24):
    split = get_split(data, "train")
    rows = np.flatnonzero(np.asarray(split.demo_index) >= 0)[:n]
    return gather_batch(split, rows)


def test_sampled_normaliser_is_exact_on_the_whole_set(data):
    mb = _batch(data)
    f, d = mb["features"].double(), mb["demo_index"]
    theta = torch.rand(len(d), 15, dtype=torch.float64, generator=torch.Generator().manual_seed(0))
    n = f.shape[1]
    full = nll(theta, f, d)
    for n_sample in (n, n + 7):
        assert torch.allclose(sampled_nll(theta, f, d, n_sample), full, rtol=1e-12, atol=1e-12)
    # the demonstration is always in the sample: alone it is the whole normaliser (NLL 0)
    assert torch.equal(sampled_nll(theta, f, d, 1), torch.zeros_like(full))


def test_sampled_normaliser_is_unbiased_in_expectation(data):
    """E[Z_hat] = Z: the mean over many samples of exp(sampled NLL) = Z_hat / exp(V_D) approaches
    exp(NLL) = Z / exp(V_D); log Z_hat is biased low (Jensen) and the bias shrinks with the sample."""
    mb = _batch(data, 6)
    f, d = mb["features"].double(), mb["demo_index"]
    theta = 0.2 * torch.rand(len(d), 15, dtype=torch.float64, generator=torch.Generator().manual_seed(1))
    full = nll(theta, f, d)
    gen = torch.Generator().manual_seed(2)
    bias = {}
    for n_sample in (8, 32):
        draws = torch.stack([sampled_nll(theta, f, d, n_sample, gen) for _ in range(3000)])
        rel = draws.exp().mean(0) / full.exp()
        assert torch.allclose(rel, torch.ones_like(rel), atol=0.05), (n_sample, rel)
        bias[n_sample] = float((draws.mean(0) - full).mean())
    assert bias[8] < 0 and bias[32] < 0 and abs(bias[32]) < abs(bias[8])


def test_bench_train_throughput_writes_its_table(tiny_dataset, tmp_path):
    """The benchmark runs the real loop for every variant and writes JSON and Markdown (values unasserted)."""
    import json

    from irlsim.cli import main

    out = tmp_path / "bench"
    args = ["bench", "--train-throughput", "--data", str(tiny_dataset), "--out", str(out)]
    # bf16 where this CPU has it natively; elsewhere that lever is refused (tests/train/test_devices.py)
    precision = "precision=bf16" if devices.bf16_problem("cpu") is None else "precision=fp32"
    args += ["--max-cycles", "16", "--repeats", "1", "--lever", "threads=1,batch_size=8"]
    args += ["--lever", precision]
    ckpt = train_stage1(tiny_dataset, _smoke(epochs=1), tmp_path / "runs")["PACNN+S"]["checkpoint"]
    assert main([*args, "--side-levers", ckpt]) == 0
    res = json.loads((out / "train_throughput.json").read_text())
    names = [v["variant"] for v in res["variants"]]
    assert names == ["baseline", "threads=1,batch_size=8", precision, "fast"]
    assert res["variants"][1]["threads"] == 1 and res["variants"][2]["precision"] == precision[10:]
    assert all(v["cycles_per_s"] > 0 for v in res["variants"])
    assert res["side_levers"]["normaliser"][0]["nll_bias_mean"] == 0.0
    assert "| fast |" in (out / "train_throughput.md").read_text()
    # a lever that is no config field: one line on stderr, exit 2, before any training
    bad = ["bench", "--train-throughput", "--data", str(tiny_dataset), "--out", str(out), "--lever", "nope=1"]
    assert main(bad) == 2
    if devices.bf16_problem("cpu") is not None:  # bf16 on a CPU without it: refused likewise
        assert main([*bad[:-1], "precision=bf16"]) == 2


def test_policy_sample_keeps_the_demonstration_and_the_order():
    from irlsim.irl.objectives import sample_policies

    rng = np.random.default_rng(0)
    demo = np.array([0, 5, 99, 42])
    policies, at, log_w = sample_policies(100, 10, demo, rng)
    assert policies.shape == (4, 10) and log_w.shape == (4, 10)
    assert (np.diff(policies, axis=1) > 0).all()  # ascending (progress order), no repeats
    assert (policies[np.arange(4), at] == demo).all()
    assert (log_w[np.arange(4), at] == 0).all()
    others = np.ones_like(log_w, bool)
    others[np.arange(4), at] = False
    assert np.allclose(log_w[others], np.log(99 / 9))
    # the whole set: every policy, weight 1, the demonstration where it was
    p, a, w = sample_policies(100, 100, demo, rng)
    assert (p == np.arange(100)).all() and (a == demo).all() and not w.any()
    with pytest.raises(ValueError, match="m >= 2"):
        sample_policies(100, 1, demo, rng)


def test_policy_sample_is_uniform_and_its_normaliser_unbiased():
    """Each other policy is drawn with probability (m - 1) / (n - 1); E[sum exp(V + log_w)] = Z."""
    from irlsim.irl.objectives import sample_policies

    n, m, draws = 40, 6, 20000
    rng = np.random.default_rng(1)
    demo = np.full(draws, 7)
    policies, _, log_w = sample_policies(n, m, demo, rng)
    counts = np.bincount(policies.ravel(), minlength=n)
    assert counts[7] == draws
    freq = np.delete(counts, 7) / draws
    assert np.allclose(freq, (m - 1) / (n - 1), atol=0.01)
    values = np.random.default_rng(2).normal(size=n)
    z_hat = (np.exp(values[policies] + log_w)).sum(1)
    assert z_hat.mean() == pytest.approx(np.exp(values).sum(), rel=0.02)


def test_weighted_metrics_with_zero_weights_are_the_plain_ones(data):
    from irlsim.irl.objectives import cycle_metrics

    mb = _batch(data)
    theta = torch.rand(len(mb["demo_index"]), 15, generator=torch.Generator().manual_seed(0))
    plain = cycle_metrics(theta, mb["features"], mb["distances"], mb["demo_index"])
    zero = torch.zeros(mb["distances"].shape)
    weighted = cycle_metrics(theta, mb["features"], mb["distances"], mb["demo_index"], zero)
    assert all(torch.equal(plain[k], weighted[k]) for k in plain)


def test_policy_sample_trains_repeatably(data, tmp_path):
    """Stage 1 on sampled policy sets: the same seed gives the same bytes, the steps differ from the
    whole set's, a sample as large as the set is the whole set (same bytes as without), the option is
    recorded only when set, and fixed-N models or a sample of one are refused in one line."""
    n = data.split_tensors("train").features.shape[1]
    runs = {}
    for name, k in (("a", 16), ("b", 16), ("full", 0), ("all", n)):
        train_stage1(data, _smoke(epochs=1, policy_sample=k), tmp_path / name)
        runs[name] = (tmp_path / name / "PACNN+S" / "checkpoint.pt").read_bytes()
    assert runs["a"] == runs["b"]
    ckpt = torch.load(tmp_path / "a" / "PACNN+S" / "checkpoint.pt", weights_only=True)
    plain = torch.load(tmp_path / "full" / "PACNN+S" / "checkpoint.pt", weights_only=True)
    every = torch.load(tmp_path / "all" / "PACNN+S" / "checkpoint.pt", weights_only=True)
    assert ckpt["config"]["policy_sample"] == 16 and "policy_sample" not in plain["config"]
    assert not all(torch.equal(ckpt["state_dict"][k], plain["state_dict"][k]) for k in plain["state_dict"])
    assert all(torch.equal(every["state_dict"][k], plain["state_dict"][k]) for k in plain["state_dict"])
    assert math.isfinite(ckpt["metrics"][-1]["val/opd"]) and math.isfinite(ckpt["metrics"][-1]["train/nll"])
    for over, words in (({"models": ["1DCNN"]}, "fixed N"), ({}, "policy_sample must be 0")):
        with pytest.raises(IrlsimError, match=words) as e:
            load_config(Stage1Config, FAST, {"policy_sample": 1 if not over else 8, **over})
        assert "\n" not in str(e.value)

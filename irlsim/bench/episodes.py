"""Benchmarks of collection, inference and the Gymnasium env (docs/design/performance.md).

Measured, never asserted: ``irlsim bench --collect`` / ``--infer`` write the figures to ``bench/``.
"""

from __future__ import annotations

import dataclasses
import statistics
import tempfile
import time
from functools import partial
from pathlib import Path
from typing import Any

import numpy as np

from irlsim.config import load_config
from irlsim.data.collection import CollectConfig, EpisodeJob, collect_episode
from irlsim.data.demonstrator import EXPERT, identity, resolve
from irlsim.executor import Job, run_jobs
from irlsim.road.scenario import DEFAULT_SCENARIO, Scenarios, load_scenario

#: the paper's scale: one hour of driving
PAPER_TRAIN_CYCLES = 17_000


def collect_one(args: tuple[Any, ...]) -> dict[str, Any]:
    """One episode as ``irlsim collect`` runs it: ``args`` (out, seed, cycles, n_policies, the command's
    :class:`~irlsim.road.scenario.Scenarios`, then optionally a resolved demonstrator and its scenario)."""
    out, seed, cycles, n_policies, scenarios, *who = args
    cfg = load_config(
        CollectConfig,
        None,
        {"max_cycles": cycles, "planner.n_policies": n_policies, "scenario.n_vehicles": 15},
        scenarios=scenarios,
    )
    if who:  # a demonstrator (resolved) and its scenario: episode ``seed`` is the seed-th ego of a recording
        cfg = dataclasses.replace(
            cfg, demonstrator=who[0], scenario=dataclasses.replace(cfg.scenario, name=who[1])
        )
    return collect_episode(EpisodeJob(out, "train", seed, seed, cfg, scenarios=scenarios))


def bench_demonstrator(
    config: Path | None, episodes: int, scenarios: Scenarios
) -> tuple[tuple[Any, ...], str]:
    """What ``collect_one`` gets beyond its sizes: () for the expert, else the ``[demonstrator]`` of the
    collect config ``config`` resolved (checked, one line) for ``episodes`` episodes and its scenario's
    name (read once into ``scenarios``); with the demonstrator's identity
    (:func:`irlsim.data.demonstrator.identity`)."""
    if config is None:
        return (), EXPERT
    cfg = load_config(CollectConfig, config, {}, scenarios=scenarios)
    if cfg.demonstrator.kind == EXPERT:
        return (), EXPERT
    name = cfg.scenario_names[0]
    demo, record = resolve(cfg.demonstrator, (scenarios(name),), cfg.scenario.step, episodes)
    return (demo, name), identity(record)


def bench_collect(
    cycles: int = 150, n_policies: int = 2500, seed: int = 0, demonstrator: Path | None = None
) -> dict[str, Any]:
    """Planning cycles per second per worker, end to end (SUMO + planner + demonstrations + Parquet).

    One episode of ``cycles`` cycles in this process, then two at once in two spawned workers; the
    wall time of the paper config (17,000 train cycles) with 2 workers is extrapolated from the latter.
    ``demonstrator``: a collect config whose ``[demonstrator]`` (on its scenario) drives instead of the
    expert (a recording's episodes ``seed`` to ``seed + 2`` are its egos of those positions).
    """
    scenarios = Scenarios()  # each road read once and handed to every episode, as 'irlsim collect' does
    scenarios(DEFAULT_SCENARIO)  # the default road's network, built once before the workers read it
    who, ident = bench_demonstrator(demonstrator, seed + 3, scenarios)
    with tempfile.TemporaryDirectory() as tmp:
        one = collect_one((tmp + "/one", seed, cycles, n_policies, scenarios, *who))
        t0 = time.perf_counter()
        jobs = [Job(str(i), (tmp + "/two", seed + i, cycles, n_policies, scenarios, *who)) for i in (1, 2)]
        # as irlsim collect runs its episodes: the local executor's spawned single-threaded workers
        done = run_jobs(collect_one, jobs, executor="local", workers=2)
        if done.failed:
            raise RuntimeError(f"benchmark episodes failed: {done.failed}")
        two = [done.results[j.key] for j in jobs]
        wall2 = time.perf_counter() - t0
    total2 = sum(r["collect/cycles"] for r in two)
    per_worker = [r["collect/cycles_per_s"] for r in two]
    rate2 = total2 / wall2  # includes the workers' start-up
    return {
        "demonstrator": ident,
        "n_policies": n_policies,
        "vehicles": 15,
        "cycles_per_episode": cycles,
        "cycles_per_s_one_worker": one["collect/cycles_per_s"],
        "cycles_per_s_per_worker_with_2": round(float(np.mean(per_worker)), 2),
        "cycles_per_s_total_with_2": round(rate2, 2),
        "paper_train_cycles": PAPER_TRAIN_CYCLES,
        "paper_wall_min_with_2_workers": round(PAPER_TRAIN_CYCLES / rate2 / 60.0, 1),
        "target": ">= 25 cycles/s per worker; paper hour <= 10 min with 2 workers",
    }


def _time_inference(
    cfg: Any, n_policies: int, repeats: int, history: int, rng: np.random.Generator
) -> dict[str, Any]:
    """PACNN + PTACNN of sizes ``cfg`` at initial weights: parameters and per-cycle inference [ms] of the
    online predictor (one thread) on one random cycle of ``n_policies`` policies."""
    # lazy: these pull torch (about 1.5 s to import); 'irlsim bench --collect' and its spawned workers
    # (which import this module for collect_one) never need it
    from irlsim.models.registry import build_model, count_parameters
    from irlsim.reward.predictor import RewardPredictor
    from irlsim.train.loading import LoadedModel

    cfg = dataclasses.replace(cfg, history=history)
    pacnn = build_model("PACNN", cfg, n_policies, None).eval()
    ptacnn = build_model("PTACNN", cfg, n_policies, None).eval()
    loaded = LoadedModel(name="PTACNN", model=ptacnn, base=pacnn, history=history, checkpoint={})
    pred = RewardPredictor(loaded, threads=1)
    f = rng.random((n_policies, 15), dtype=np.float32)
    cp = rng.random((n_policies, 10, 3), dtype=np.float32)
    a = rng.random((n_policies, 10, 2), dtype=np.float32)
    for _ in range(5):
        pred.predict(f, cp, a)
    ms = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        pred.predict(f, cp, a)
        ms.append((time.perf_counter() - t0) * 1e3)
    return {
        "pacnn_parameters": count_parameters(pacnn),
        "ptacnn_parameters": count_parameters(ptacnn),
        "median_ms": round(statistics.median(ms), 3),
        "p90_ms": round(float(np.percentile(ms, 90)), 3),
    }


def bench_infer(
    n_policies: int = 2500, repeats: int = 50, batch: int = 32, history: int = 10, seed: int = 0
) -> dict[str, Any]:
    """PACNN + PTACNN inference per cycle (one thread), for the default (small) sizes and for the near-paper
    sizes of ``ModelConfig.paper()`` (keys ``paper_*``), and stage-1 training throughput (cycles/s) of
    the default sizes."""
    # lazy: torch and the modules that pull it, as in _time_inference
    import torch

    from irlsim.irl.objectives import nll
    from irlsim.models.registry import ModelConfig, build_model

    torch.manual_seed(seed)
    rng = np.random.default_rng(seed)
    cfg = ModelConfig(history=history)
    small = _time_inference(cfg, n_policies, repeats, history, rng)
    paper = _time_inference(ModelConfig.paper(), n_policies, repeats, history, rng)

    # training throughput: PACNN forward + NLL + backward on mini-batches of cycles, 2 threads
    torch.set_num_threads(2)
    train_model = build_model("PACNN", cfg, n_policies, None).train()
    opt = torch.optim.Adam(train_model.parameters(), lr=1e-3)
    fb = torch.rand(batch, n_policies, 15)
    cpb = torch.rand(batch, n_policies, 10, 3)
    ab = torch.rand(batch, n_policies, 10, 2)
    demo = torch.randint(0, n_policies, (batch,))
    times = []
    for i in range(6):
        t0 = time.perf_counter()
        out = train_model(fb, cpb, ab)
        loss = nll(out["theta"], fb, demo).mean()
        opt.zero_grad()
        loss.backward()
        opt.step()
        if i > 0:
            times.append(time.perf_counter() - t0)
    step = statistics.median(times)
    return {
        "n_policies": n_policies,
        "history": history,
        "pacnn_parameters": small["pacnn_parameters"],
        "ptacnn_parameters": small["ptacnn_parameters"],
        "infer_median_ms": small["median_ms"],
        "infer_p90_ms": small["p90_ms"],
        "paper_pacnn_parameters": paper["pacnn_parameters"],
        "paper_ptacnn_parameters": paper["ptacnn_parameters"],
        "paper_infer_median_ms": paper["median_ms"],
        "paper_infer_p90_ms": paper["p90_ms"],
        "train_cycles_per_s_pacnn_2_threads": round(batch / step, 1),
        "train_epoch_min_17000_cycles": round(PAPER_TRAIN_CYCLES / (batch / step) / 60.0, 2),
        "target": "inference <= 10 ms per cycle; one epoch over 17,000 cycles <= 5 min on 2 cores",
        "what": "infer_*: default sizes (configs/train/stage*.toml); paper_*: ModelConfig.paper() (latent "
        "256, LSTM 256, FC 512); per cycle incl. the PTACNN mixture, one thread, initial weights",
    }


# ------------------------------------------------------------------------------------------ Gymnasium env


def _make_env(n_policies: int) -> Any:
    # lazy: gymnasium is the optional extra 'gym'; only 'irlsim bench --env' needs it
    import gymnasium as gym

    import irlsim.envs  # noqa: F401  (registers the ids)

    return gym.make("irlsim/Planning-v0", overrides={"planner.n_policies": n_policies})


def bench_env(steps: int = 200, n_policies: int = 500, n_envs: int = 2, seed: int = 0) -> dict[str, Any]:
    """Environment steps (planning cycles) per second with uniformly random actions and the expert-theta
    reward: one ``irlsim/Planning-v0`` in this process, then ``n_envs`` in a
    ``gymnasium.vector.AsyncVectorEnv`` (one libsumo per subprocess, spawned). Resets are outside the
    single env's timing; the vectorised figure counts every step of every env over the wall time of
    ``steps`` vector steps (autoresets included)."""
    from gymnasium.vector import AsyncVectorEnv  # lazy: the optional extra 'gym'

    load_scenario()  # the default road's network, built once before the workers read it
    env = _make_env(n_policies)
    rng = np.random.default_rng(seed)
    env.reset(seed=seed)
    n = 0
    t_single = 0.0
    while n < steps:
        t0 = time.perf_counter()
        _, _, term, trunc, _ = env.step(int(rng.integers(0, n_policies)))
        t_single += time.perf_counter() - t0
        n += 1
        if term or trunc:
            env.reset(seed=seed + n)
    env.close()
    venv = AsyncVectorEnv([partial(_make_env, n_policies)] * n_envs, context="spawn")
    venv.reset(seed=seed)
    t0 = time.perf_counter()
    for _ in range(steps):
        venv.step(rng.integers(0, n_policies, size=n_envs))
    t_vec = time.perf_counter() - t0
    venv.close()
    return {
        "n_policies": n_policies,
        "steps": steps,
        "env_steps_per_s_single": round(steps / t_single, 1),
        "env_steps_per_s_vector": round(n_envs * steps / t_vec, 1),
        "n_envs": n_envs,
    }

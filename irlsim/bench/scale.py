"""``irlsim bench --scale``: collection with the local pool against Ray on the same machine and worker
count, scaling from 1 to 2 workers on a simulated two-node Ray cluster, and stage-1 training cycles/s
per torch device and precision. Measured, never asserted.
"""

from __future__ import annotations

import logging
import tempfile
import time
from typing import Any

import numpy as np

from irlsim.bench.episodes import collect_one
from irlsim.errors import IrlsimError
from irlsim.executor import Job, run_jobs
from irlsim.road.scenario import DEFAULT_SCENARIO, Scenarios

#: episodes of each timed collection (two per worker with 2 workers)
EPISODES = 4


def _collect_job(args: tuple[str, int, int, int, Scenarios]) -> dict[str, Any]:  # top level: picklable
    return collect_one(args)


def _timed_collection(
    executor: str, workers: int, root: str, seed: int, cycles: int, n_policies: int, episodes: int
) -> dict[str, Any]:
    """Wall time of ``episodes`` collection episodes through irlsim.executor (workers' start included)."""
    scenarios = Scenarios()  # the road read once and handed to every episode, as 'irlsim collect' does
    scenarios(DEFAULT_SCENARIO)
    jobs = [Job(str(i), (root, seed + i, cycles, n_policies, scenarios)) for i in range(episodes)]
    t0 = time.perf_counter()
    res = run_jobs(_collect_job, jobs, executor=executor, workers=workers)
    wall = time.perf_counter() - t0
    if res.failed:
        raise RuntimeError(f"benchmark episodes failed: {res.failed}")
    total = sum(r["collect/cycles"] for r in res.results.values())
    return {
        "episodes": episodes,
        "cycles": total,
        "wall_s": round(wall, 2),
        "cycles_per_s": round(total / wall, 2),
    }


def bench_executors(cycles: int, n_policies: int, seed: int, workers: int = 2) -> dict[str, Any]:
    """The same episodes with the local pool and with Ray (a local Ray of ``workers`` CPUs, started before
    the clock: its start-up is reported apart), each end to end, workers' start included."""
    import ray  # lazy: the optional extra 'ray' (bench_scale checks it is there)

    out: dict[str, Any] = {"workers": workers, "n_policies": n_policies, "cycles_per_episode": cycles}
    with tempfile.TemporaryDirectory() as tmp:
        out["local"] = _timed_collection("local", workers, tmp + "/local", seed, cycles, n_policies, EPISODES)
        t0 = time.perf_counter()
        ray.init(
            num_cpus=workers, include_dashboard=False, log_to_driver=False, logging_level=logging.WARNING
        )
        out["ray_start_s"] = round(time.perf_counter() - t0, 2)
        try:
            out["ray"] = _timed_collection("ray", workers, tmp + "/ray", seed, cycles, n_policies, EPISODES)
        finally:
            ray.shutdown()
    out["ray_over_local"] = round(out["ray"]["cycles_per_s"] / out["local"]["cycles_per_s"], 3)
    return out


def bench_cluster_scaling(cycles: int, n_policies: int, seed: int) -> dict[str, Any]:
    """Two episodes on a simulated two-node cluster (1 CPU per node): one task at a time, then two."""
    # lazy: the optional extra 'ray'
    import ray
    from ray.cluster_utils import Cluster

    cluster = Cluster(initialize_head=True, head_node_args={"num_cpus": 1, "include_dashboard": False})
    cluster.add_node(num_cpus=1)
    ray.init(
        address=cluster.address, include_dashboard=False, log_to_driver=False, logging_level=logging.WARNING
    )
    try:
        with tempfile.TemporaryDirectory() as tmp:
            one = _timed_collection("ray", 1, tmp + "/one", seed, cycles, n_policies, 2)
            two = _timed_collection("ray", 2, tmp + "/two", seed, cycles, n_policies, 2)
    finally:
        ray.shutdown()
        cluster.shutdown()
    return {
        "nodes": 2,
        "one_worker": one,
        "two_workers": two,
        "speedup_1_to_2": round(two["cycles_per_s"] / one["cycles_per_s"], 3),
    }


def _train_step(model: Any, opt: Any, mb: dict[str, Any]) -> None:
    """One stage-1 PACNN+S optimizer step as the training loop takes it (irlsim.train.stage1)."""
    # lazy: torch; the spawned collection workers import this module for _collect_job and never need it
    from irlsim import devices
    from irlsim.irl.objectives import attention_loss, attention_target, cycle_metrics

    out = devices.forward(model, mb["features"], mb["control_points"], mb["actions"])
    loss = cycle_metrics(out["theta"], mb["features"], mb["distances"], mb["demo_index"])["nll"].mean()
    loss = (
        loss
        + attention_loss(out["attention_pooled"], attention_target(mb["distances"], model.pool, 0.5)).mean()
    )
    opt.zero_grad()
    loss.backward()
    opt.step()


def bench_training(
    n_policies: int = 500, steps: int = 20, batch: int = 32, threads: int = 2
) -> dict[str, Any]:
    """Stage-1 PACNN+S training steps (forward, NLL + attention loss, backward, Adam) in cycles/s, per
    available device and precision, default network sizes, synthetic cycles of ``n_policies`` policies."""
    # lazy: torch and the modules that pull it, as in _train_step
    import torch

    from irlsim import devices
    from irlsim.bench.synthetic import make_synthetic_dataset
    from irlsim.models.normalization import compute_feature_stats
    from irlsim.models.registry import ModelConfig, build_model
    from irlsim.train.batching import gather_batch
    from irlsim.train.repro import num_threads

    data = make_synthetic_dataset(n_train=batch * 4, n_eval=8, n_policies=n_policies, seed=0)
    train = data.split_tensors("train")
    stats = compute_feature_stats(train, batch * 4)
    names = ["cpu"] + (["cuda"] if torch.cuda.is_available() else [])
    results: dict[str, Any] = {
        "model": "PACNN+S",
        "n_policies": n_policies,
        "batch": batch,
        "threads": threads,
    }
    for dev in names:
        for precision in devices.PRECISIONS:
            if precision == "bf16" and (problem := devices.bf16_problem(dev)) is not None:
                results[f"{dev}/bf16_not_run"] = problem  # refused there: nothing to time
                continue
            with num_threads(threads), devices.use(dev, precision):
                torch.manual_seed(0)
                model = build_model("PACNN+S", ModelConfig(), n_policies, stats).to(devices.current_device())
                opt = torch.optim.Adam(model.parameters(), lr=1e-3)

                for i in range(3):  # warm-up
                    _train_step(
                        model, opt, gather_batch(train, np.arange(i % 4 * batch, (i % 4 + 1) * batch))
                    )
                if dev == "cuda":
                    torch.cuda.synchronize()
                t0 = time.perf_counter()
                for i in range(steps):
                    _train_step(
                        model, opt, gather_batch(train, np.arange(i % 4 * batch, (i % 4 + 1) * batch))
                    )
                if dev == "cuda":
                    torch.cuda.synchronize()
                wall = time.perf_counter() - t0
            results[f"{dev}/{precision}_cycles_per_s"] = round(steps * batch / wall, 1)
    if "cpu/bf16_cycles_per_s" in results:
        results["cpu_bf16_over_fp32"] = round(
            results["cpu/bf16_cycles_per_s"] / results["cpu/fp32_cycles_per_s"], 3
        )
    results["devices_measured"] = names
    return results


def bench_scale(cycles: int = 150, n_policies: int = 2500, seed: int = 0) -> dict[str, Any]:
    try:
        import ray  # noqa: F401  (lazy: the optional extra 'ray')
    except ImportError:
        raise IrlsimError("bench --scale needs Ray: pip install -e '.[ray]'") from None
    executors = bench_executors(cycles, n_policies, seed)
    scaling = bench_cluster_scaling(cycles, n_policies, seed + 100)
    training = bench_training()
    return {
        "collect_local_cycles_per_s": executors["local"]["cycles_per_s"],
        "collect_ray_cycles_per_s": executors["ray"]["cycles_per_s"],
        "ray_over_local": executors["ray_over_local"],
        "ray_start_s": executors["ray_start_s"],
        "cluster_speedup_1_to_2_workers": scaling["speedup_1_to_2"],
        **{k: v for k, v in training.items() if k.endswith("_cycles_per_s") or k == "cpu_bf16_over_fp32"},
        "details": {"executors": executors, "cluster": scaling, "training": training},
    }

"""``irlsim bench --train-throughput --side-levers CHECKPOINT``: the two training levers that are no
config option, measured in isolation on a dataset and a trained stage-1 checkpoint (its thetas on the
validation split). Measured, never asserted.

- the sampled max-ent normaliser (:func:`irlsim.irl.objectives.sampled_nll`): the seconds of the loss
  (forward and backward of the NLL on a mini-batch of thetas) with the whole policy set and with samples
  of n policies, and the estimator's bias, mean(sampled NLL) - NLL, over the validation cycles;
- features read in 16 bit: the seconds of gathering a mini-batch (features, control points, actions)
  from the memory-mapped float32 cache against from an in-memory float16 copy, and the round trip's
  largest relative error.
"""

from __future__ import annotations

import statistics
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
import torch

from irlsim.irl.objectives import nll, sampled_nll
from irlsim.train.batching import as_dataset, gather_batch, get_split, predict_split
from irlsim.train.loading import load_model
from irlsim.train.repro import num_threads


def _median_s(fn: Callable[[], Any], repeats: int) -> float:
    times = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t0)
    return statistics.median(times)


def normaliser_rows(
    split: Any, thetas: np.ndarray, sizes: tuple[int, ...], batch: int
) -> list[dict[str, Any]]:
    """Per sample size n (0 = the whole set): loss seconds per mini-batch and the NLL bias [nats]."""
    valid = np.flatnonzero(np.asarray(split.demo_index) >= 0)
    f = torch.as_tensor(np.asarray(split.features[valid]))
    d = torch.as_tensor(np.asarray(split.demo_index[valid]), dtype=torch.int64)
    th = torch.as_tensor(thetas[valid])
    full = nll(th.double(), f.double(), d)
    gen = torch.Generator().manual_seed(0)
    rows = []
    for n in sizes:

        def loss(n: int = n) -> None:
            t = th[:batch].clone().requires_grad_(True)
            value = nll(t, f[:batch], d[:batch]) if n == 0 else sampled_nll(t, f[:batch], d[:batch], n, gen)
            value.mean().backward()

        seconds = _median_s(loss, 20)
        draws = [sampled_nll(th.double(), f.double(), d, n, gen) for _ in range(20)] if n else [full]
        bias = (torch.stack(draws).mean(0) - full).double()
        rows.append(
            {
                "policies": n or int(f.shape[1]),
                "loss_ms_per_batch": round(1e3 * seconds, 2),
                "nll_bias_mean": round(float(bias.mean()), 4),
                "nll_bias_rel": round(float(bias.mean() / full.mean()), 4),
            }
        )
    return rows


def sixteen_bit_row(split: Any, batch: int) -> dict[str, Any]:
    """Gather seconds per mini-batch: float32 memory map vs an in-memory float16 copy, and the error."""
    n = min(int(split.features.shape[0]), 1024)
    half = {
        k: np.asarray(getattr(split, k)[:n]).astype(np.float16)
        for k in ("features", "control_points", "actions")
    }
    rng = np.random.default_rng(0)
    picks = [np.sort(rng.choice(n, min(batch, n), replace=False)) for _ in range(20)]

    def from_half() -> None:
        for rows in picks[:5]:
            for a in half.values():
                torch.as_tensor(a[rows]).float()

    err = max(
        float(
            np.max(
                np.abs(half[k].astype(np.float32) - np.asarray(getattr(split, k)[:n]))
                / np.maximum(np.abs(np.asarray(getattr(split, k)[:n])), 1e-3)
            )
        )
        for k in half
    )
    return {
        "gather_fp32_mmap_ms": round(
            1e3 * _median_s(lambda: [gather_batch(split, r) for r in picks[:5]], 5) / 5, 2
        ),
        "gather_fp16_ram_ms": round(1e3 * _median_s(from_half, 5) / 5, 2),
        "max_rel_error": round(err, 5),
    }


def bench_side_levers(data: Path, checkpoint: Path, batch: int = 128, threads: int = 2) -> dict[str, Any]:
    """The sampled normaliser and the 16-bit features on ``data``'s validation split, with the thetas of
    the stage-1 model in ``checkpoint``."""
    dataset = as_dataset(data)
    split = get_split(dataset, "validation")
    with num_threads(threads), torch.no_grad():
        thetas = predict_split(load_model(checkpoint).model, split)["theta"]
    with num_threads(threads):
        n = int(split.features.shape[1])
        sizes = tuple(s for s in (0, 256, 128, 64, 32) if s < n)
        return {
            "checkpoint": str(checkpoint),
            "batch": batch,
            "normaliser": normaliser_rows(split, thetas, sizes, batch),
            "sixteen_bit": sixteen_bit_row(split, batch),
        }

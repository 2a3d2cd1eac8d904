"""Reproducibility of training: torch thread count, deterministic kernels and the provenance record."""

from __future__ import annotations

from collections.abc import Iterator
from contextlib import contextmanager
from typing import Any

import torch

from irlsim.devices import describe


def provenance() -> dict[str, Any]:
    """What besides seeds and data decides the trained bytes: torch's version, its CPU thread count and
    the vector instruction set its kernels dispatch to. The same seed and data give the same weights on
    every run with these three equal; a different thread count or instruction set (another CPU) changes
    the float summation order of convolutions and matrix products, so the weights differ in the last bits
    and the selected epoch (and Table I) can differ visibly."""
    return {
        "torch": str(torch.__version__),  # a TorchVersion, which weights_only loading refuses
        "threads": int(torch.get_num_threads()),
        "cpu_capability": str(torch.backends.cpu.get_cpu_capability()),
        **describe(),  # device (and GPU name) and precision
    }


@contextmanager
def num_threads(threads: int) -> Iterator[None]:
    """Run torch with ``threads`` CPU threads; restores the caller's count after."""
    old = torch.get_num_threads()
    torch.set_num_threads(threads)
    try:
        yield
    finally:
        torch.set_num_threads(old)


@contextmanager
def deterministic(threads: int) -> Iterator[None]:
    """Run torch with ``threads`` CPU threads and deterministic algorithms only (an op without a
    deterministic CPU kernel raises instead of silently varying between runs); restores both after."""
    old_det = torch.are_deterministic_algorithms_enabled()
    torch.use_deterministic_algorithms(True)
    try:
        with num_threads(threads):
            yield
    finally:
        torch.use_deterministic_algorithms(old_det)

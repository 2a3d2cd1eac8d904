"""``irlsim bench --growth``: the curves of training and inference (imports torch when called).

A stage-1 PACNN is trained by :func:`irlsim.train.stage1.train_stage1` (the training of ``irlsim train``:
shuffled mini-batches of 32 cycles, NLL, Adam, a checkpoint per epoch; on ``train_threads`` threads)
for four epochs on the synthetic known-reward dataset of :mod:`irlsim.bench.synthetic`, at each size.
The epoch time is the faster of the second and third (the first warms up, the fourth also validates).
The resident memory of the training is the peak resident set while it runs minus the process's resident
set before its dataset was built: the dataset, the network, the optimizer, the mini-batches and the
feature statistics' pass (chunks of 256 cycles in float64). One small training runs first and is not
counted, so that what torch sets up once per process (thread pools, kernels) is not charged to the first
size. Inference is the trained PACNN's theta for one policy set, through
:class:`irlsim.reward.predictor.RewardPredictor` on one thread, at each policy count.
"""

from __future__ import annotations

import ctypes
import gc
import resource
import sys
import tempfile
import threading
from pathlib import Path

import numpy as np

from irlsim.bench.growth import Curve, GrowthSizes, Progress, time_for

STATUS = Path("/proc/self/status")


def _status_mb(key: str) -> float:
    """A memory line of /proc/self/status [MB] (``VmRSS``: now, ``VmHWM``: the peak)."""
    for line in STATUS.read_text().splitlines():
        if line.startswith(key + ":"):
            return int(line.split()[1]) / 1024.0
    raise KeyError(key)


def _trim() -> None:
    """Hand freed heap memory back to the system (glibc), so the resident set is what is in use."""
    gc.collect()
    try:
        ctypes.CDLL(None).malloc_trim(0)
    except (AttributeError, OSError):  # not glibc
        pass


def rss_mb() -> float:
    """The resident set of this process now [MB]."""
    if STATUS.is_file():
        return _status_mb("VmRSS")
    scale = 1.0 if sys.platform == "darwin" else 1024.0  # ru_maxrss: bytes on macOS, kB elsewhere
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / scale / 1024.0


class PeakRss:
    """The peak resident set [MB] within a ``with`` block: Linux's peak counter, reset at the start
    (``/proc/self/clear_refs``); where that cannot be reset, the resident set sampled every 5 ms."""

    def __init__(self) -> None:
        self.mb = 0.0
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None

    def __enter__(self) -> PeakRss:
        try:
            Path("/proc/self/clear_refs").write_text("5")
        except OSError:
            self.mb = rss_mb()
            self._thread = threading.Thread(target=self._sample, daemon=True)
            self._thread.start()
        return self

    def _sample(self) -> None:
        while not self._stop.wait(0.005):
            self.mb = max(self.mb, rss_mb())

    def __exit__(self, *exc: object) -> None:
        if self._thread is None:
            self.mb = _status_mb("VmHWM")
        else:
            self._stop.set()
            self._thread.join()
            self.mb = max(self.mb, rss_mb())


def train_point(
    n_cycles: int, n_policies: int, seed: int, out: Path, threads: int = 1
) -> tuple[float, float, Path]:
    """Train a PACNN for four epochs on a synthetic dataset of ``n_cycles`` train cycles of
    ``n_policies`` policies into ``out``; returns (seconds of the faster of the second and third epoch,
    resident memory of the training [MB], the checkpoint)."""
    from irlsim.bench.synthetic import make_synthetic_dataset
    from irlsim.train.config import Stage1Config
    from irlsim.train.metrics_log import read_metrics
    from irlsim.train.stage1 import train_stage1

    _trim()
    before = rss_mb()
    data = make_synthetic_dataset(n_train=n_cycles, n_eval=8, n_policies=n_policies, seed=seed)
    _trim()  # the dataset's temporaries
    cfg = Stage1Config(
        models=("PACNN",), epochs=4, validate_every=4, threads=threads, seed=seed, tensorboard=False
    )
    with PeakRss() as peak:
        train_stage1(data, cfg, out)
    del data
    rows = read_metrics(out / "PACNN" / "metrics.csv")
    epoch_s = min(float(r["time/epoch_s"]) for r in rows[1:3])
    return epoch_s, peak.mb - before, out / "PACNN" / "checkpoint.pt"


def _infer_ms(checkpoint: Path, n_policies: int, seconds: float, seed: int) -> float:
    """Median time [ms] of the trained model's theta for one random policy set, one thread."""
    from irlsim.reward.predictor import RewardPredictor

    pred = RewardPredictor(checkpoint, threads=1)
    rng = np.random.default_rng(seed)
    f = rng.random((n_policies, 15), dtype=np.float32)
    cp = rng.random((n_policies, 10, 3), dtype=np.float32)
    a = rng.random((n_policies, 10, 2), dtype=np.float32)
    return time_for(lambda: pred.predict(f, cp, a), seconds)


def _sweep(
    name: str, points: list[tuple[int, int]], seed: int, threads: int, tmp: Path, say: Progress
) -> tuple[list[float], list[float], list[Path]]:
    seconds, memory, checkpoints = [], [], []
    for c, n in points:
        s, mb, ckpt = train_point(c, n, seed, tmp / f"{name}_c{c}_n{n}" / "stage1", threads)
        seconds.append(s)
        memory.append(mb)
        checkpoints.append(ckpt)
        say(f"training, {c} cycles x {n} policies: {s:.2f} s per epoch, {mb:.0f} MB resident")
    return seconds, memory, checkpoints


def training_curves(sizes: GrowthSizes, seed: int, say: Progress) -> list[Curve]:
    """Epoch time and resident memory against cycles and against policies; inference against policies."""
    by_c = [(c, sizes.train_policies_at) for c in sizes.train_cycles]
    by_n = [(sizes.train_cycles_at, n) for n in sizes.train_policies]
    at_n = f"{sizes.train_policies_at} policies per cycle"
    at_c = f"{sizes.train_cycles_at} train cycles"
    with tempfile.TemporaryDirectory() as folder:
        tmp = Path(folder)
        threads = sizes.train_threads
        warm_up = min(sizes.train_cycles), min(sizes.train_policies)
        train_point(*warm_up, seed, tmp / "warm-up" / "stage1", threads)
        epoch_c, mem_c, ckpts = _sweep("cycles", by_c, seed, threads, tmp, say)
        epoch_n, mem_n, _ = _sweep("policies", by_n, seed, threads, tmp, say)
        infer = []
        for n in sizes.policies:
            infer.append(_infer_ms(ckpts[0], n, sizes.point_s, seed))
            say(f"inference, {n} policies: {infer[-1]:.2f} ms")
    xc = [float(c) for c, _ in by_c]
    xn = [float(n) for _, n in by_n]
    pacnn = f"PACNN (default sizes), batch 32, {threads} thread{'s' if threads > 1 else ''}"
    by_cycles, by_policies = f"{pacnn}, {at_n}", f"{pacnn}, {at_c}"
    model = f"the PACNN trained on {by_c[0][0]} cycles x {by_c[0][1]} policies, one thread"
    xi = [float(n) for n in sizes.policies]
    return [
        Curve("train_cycles", "training epoch vs cycles", "cycles", "s", by_cycles, xc, epoch_c),
        Curve("train_policies", "training epoch vs policies", "policies", "s", by_policies, xn, epoch_n),
        Curve("memory_cycles", "training memory vs cycles", "cycles", "MB", by_cycles, xc, mem_c),
        Curve("memory_policies", "training memory vs policies", "policies", "MB", by_policies, xn, mem_n),
        Curve("infer_policies", "inference vs policies", "policies", "ms", model, xi, infer),
    ]

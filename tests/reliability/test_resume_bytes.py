"""Checkpoints byte-identical after any resume: a training interrupted by SIGINT or SIGTERM and run again
writes the bytes of an uninterrupted run (the sha256 comparison the reproducibility promise makes)."""

import hashlib
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from irlsim.cli import main
from irlsim.train.checkpoint import canonical

ROOT = Path(__file__).resolve().parents[2]


def _train_cmd(data: Path, out: Path, model: str, epochs: int) -> list[str]:
    return [
        sys.executable,
        "-m",
        "irlsim.cli",
        "train",
        "--stage",
        "1",
        "--config",
        str(ROOT / "configs/train/tiny_stage1.toml"),
        "--data",
        str(data),
        "--set",
        f'models=["{model}"]',
        "--set",
        f"epochs={epochs}",
        "--out",
        str(out),
    ]


def _low_priority_with_default_sigint() -> None:
    """In the child before exec: the lowest priority (a busy machine still lets the test see it mid-run)
    and SIGINT's default action, which a test run started in the background (nohup, '&') would have
    ignored, and an ignored signal stays ignored across exec (Python then installs no handler)."""
    os.nice(19)
    signal.signal(signal.SIGINT, signal.SIG_DFL)


def _sha(path: Path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


@pytest.mark.parametrize(
    "sig, model",
    [(signal.SIGINT, "PACNN+S"), pytest.param(signal.SIGTERM, "LIRL", marks=pytest.mark.slow)],
)
def test_a_checkpoint_resumed_after_a_signal_has_the_bytes_of_an_uninterrupted_run(
    tiny_dataset, tmp_path, sig, model
):
    env = dict(os.environ, PYTHONPATH=str(ROOT))
    # a checkpoint every epoch (about 0.07 s each here): the signal, sent within 20 ms of the first one,
    # finds the lowest-priority run far from its 30th
    epochs = 30
    whole, cut = tmp_path / "whole", tmp_path / "cut"
    # the uninterrupted run in this process (an interpreter's start-up less; training sets and restores its
    # own threads and determinism), the interrupted and resumed ones as a user's commands
    assert main(_train_cmd(tiny_dataset, whole, model, epochs)[3:]) == 0
    p = subprocess.Popen(
        _train_cmd(tiny_dataset, cut, model, epochs),
        env=env,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        preexec_fn=_low_priority_with_default_sigint,
    )
    ckpt = cut / "stage1" / model / "checkpoint.pt"
    deadline = time.monotonic() + 120
    while not ckpt.exists() and p.poll() is None and time.monotonic() < deadline:
        time.sleep(0.02)
    p.send_signal(sig)
    p.communicate(timeout=120)
    assert p.returncode != 0, "the run ended before the signal: raise epochs"
    subprocess.run(_train_cmd(tiny_dataset, cut, model, epochs), env=env, check=True, capture_output=True)
    assert _sha(ckpt) == _sha(whole / "stage1" / model / "checkpoint.pt")


def test_canonical_payloads_pickle_by_value():
    """Equal payloads whose strings are distinct objects (a loaded optimizer's keys) give equal bytes."""
    import io

    import torch

    key = "".join(["l", "r"])  # equal to 'lr', another object
    shared = {"config": {"lr": 0.1}, "optimizer": {"lr": 0.1}}
    loaded = {"config": {"lr": 0.1}, "optimizer": {key: 0.1}}
    assert key is not "lr"  # noqa: F632
    buf_a, buf_b = io.BytesIO(), io.BytesIO()
    torch.save(canonical(shared), buf_a)
    torch.save(canonical(loaded), buf_b)
    assert buf_a.getvalue() == buf_b.getvalue()

"""Where torch runs (``--device``) and in what precision (``--precision``) for train, evaluate and drive.

``use(device, precision)`` sets both for a block; the training loop, the batch builders, the model loaders
and the online predictor read them (``current()``), so no function signature carries them:

- ``to_device(t)``: a batch tensor onto the device; on CUDA through pinned (page-locked) memory with a
  non-blocking copy, so the copy overlaps the previous step's kernels.
- ``forward(model, *args)``: the model's forward pass, under ``torch.autocast`` in bf16 when asked (on the
  CPU too), with its floating outputs cast back to float32: losses, metrics and everything written are
  computed in float32 from them.
- ``to_numpy(t)``: back to the host.

Checkpoints are always written and read with CPU tensors (``map_location='cpu'``) and moved after
loading, so a model trained on any device loads on any other. ``describe()`` goes into every provenance.
"""

from __future__ import annotations

from collections.abc import Iterator
from contextlib import contextmanager, nullcontext
from typing import Any

import torch

from irlsim.errors import IrlsimError

DEVICES_HELP = "auto (CUDA when present, else CPU), cpu, cuda, cuda:N or mps"
PRECISIONS = ("fp32", "bf16")

_current: list[tuple[torch.device, str]] = [(torch.device("cpu"), "fp32")]


def resolve_device(spec: str) -> torch.device:
    """``--device`` as a torch.device that exists here, or a one-line IrlsimError."""
    spec = spec.strip().lower()
    if spec == "auto":
        return torch.device("cuda") if torch.cuda.is_available() else torch.device("cpu")
    if spec == "cpu":
        return torch.device("cpu")
    if spec == "mps":
        mps = getattr(torch.backends, "mps", None)
        if mps is None or not mps.is_available():
            raise IrlsimError("--device mps: no Apple MPS device is available here: use --device cpu or auto")
        return torch.device("mps")
    if spec == "cuda" or spec.startswith("cuda:"):
        index = spec.partition(":")[2]
        if index and not index.isdigit():
            raise IrlsimError(f"--device {spec}: a CUDA device is cuda or cuda:N (N = 0, 1, ...)")
        if not torch.cuda.is_available():
            raise IrlsimError(
                f"--device {spec}: no CUDA device is available to this torch ({torch.__version__}): use "
                "--device cpu (or auto), or install a CUDA build of torch on a machine with a GPU"
            )
        count = torch.cuda.device_count()
        if index and int(index) >= count:
            raise IrlsimError(
                f"--device {spec}: this machine has {count} CUDA device(s), cuda:0..{count - 1}"
            )
        return torch.device(spec)
    raise IrlsimError(f"--device {spec!r} is not a device: choose {DEVICES_HELP}")


def check_precision(precision: str) -> str:
    if precision not in PRECISIONS:
        raise IrlsimError(f"--precision must be one of {', '.join(PRECISIONS)}, got {precision!r}")
    return precision


@contextmanager
def use(device: torch.device | str = "cpu", precision: str = "fp32") -> Iterator[None]:
    """Run the block's training / inference on ``device`` in ``precision``; restores the previous pair."""
    dev = device if isinstance(device, torch.device) else resolve_device(device)
    _current.append((dev, check_precision(precision)))
    try:
        yield
    finally:
        _current.pop()


def current() -> tuple[torch.device, str]:
    return _current[-1]


def current_device() -> torch.device:
    return _current[-1][0]


def to_device(t: torch.Tensor) -> torch.Tensor:
    """``t`` on the current device (a no-op on the CPU); CUDA copies go through pinned memory, async."""
    dev = current_device()
    if dev.type == "cpu":
        return t
    if dev.type == "cuda":
        return t.pin_memory().to(dev, non_blocking=True)
    return t.to(dev)


def autocast() -> Any:
    """``torch.autocast`` in bf16 on the current device when the precision is bf16, else nothing."""
    dev, precision = current()
    if precision == "fp32":
        return nullcontext()
    return torch.autocast(device_type=dev.type, dtype=torch.bfloat16)


def forward(model: torch.nn.Module, *args: torch.Tensor) -> dict[str, torch.Tensor]:
    """``model(*args)`` in the current precision; floating outputs come back as float32."""
    with autocast():
        out = model(*args)
    return {k: v.float() if torch.is_tensor(v) and v.is_floating_point() else v for k, v in out.items()}


def to_numpy(t: torch.Tensor) -> Any:
    return t.detach().cpu().numpy()


def describe() -> dict[str, Any]:
    """The current device and precision for a provenance record (with the GPU's name on CUDA)."""
    dev, precision = current()
    out: dict[str, Any] = {"device": str(dev), "precision": precision}
    if dev.type == "cuda":
        out["device_name"] = torch.cuda.get_device_name(dev)
    return out


def add_arguments(p: Any, what: str) -> None:
    """``--device`` and ``--precision`` of a command (``what``: 'training', 'inference', ...)."""
    p.add_argument(
        "--device", default="auto", help=f"torch device of the {what}: {DEVICES_HELP} (default: auto)"
    )
    p.add_argument(
        "--precision",
        choices=PRECISIONS,
        default="fp32",
        help=f"fp32 (default) or bf16: the {what}'s forward passes under torch.autocast in bfloat16 "
        "(CPU too)",
    )

"""Where torch runs (``--device``) and in what precision (``--precision``) for train, evaluate and drive.

``use(device, precision)`` sets both for a block; the training loop, the batch builders, the model loaders
and the online predictor read them (``current()``), so no function signature carries them:

- ``to_device(t)``: a batch tensor onto the device; on CUDA through pinned (page-locked) memory with a
  non-blocking copy, so the copy overlaps the previous step's kernels.
- ``forward(model, *args)``: the model's forward pass, under ``torch.autocast`` in bf16 when asked (on the
  CPU too), with its floating outputs cast back to float32: losses, metrics and everything written are
  computed in float32 from them.
- ``to_numpy(t)``: back to the host.

bf16 runs only where the hardware has a bf16 path for every operation irlsim uses
(:func:`bf16_problem`): a CPU without oneDNN's bf16 support (no AVX-512 or AMX, e.g. an AVX2-only CPU)
runs bf16 emulated, measured 8x slower than fp32 for a Linear layer on an AVX2 EPYC, and has no bf16
kernel for PTACNN's LSTM at all. There ``--precision bf16`` is refused in one line before any work
(:func:`resolve`, and :func:`use` for library callers) rather than run slower and less exact.

Checkpoints are always written and read with CPU tensors (``map_location='cpu'``) and moved after
loading, so a model trained on any device loads on any other. ``describe()`` goes into every provenance.
"""

from __future__ import annotations

import functools
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


def bf16_problem(device: torch.device | str = "cpu") -> str | None:
    """Why bf16 cannot run on ``device`` here (one clause), or None where it can.

    The CPU needs oneDNN's bf16 path (AVX-512 or AMX; torch's own emulation elsewhere is several times
    slower than fp32); CUDA needs a GPU with bf16. On every device a tiny probe of the operations irlsim's
    networks use (Conv1d, Linear, a 2-layer LSTM, forward and backward) must run under autocast: that is
    what catches a path oneDNN lacks, also where ``ONEDNN_MAX_CPU_ISA`` limits it. Cached per device."""
    dev = device if isinstance(device, torch.device) else resolve_device(device)
    return _bf16_problem(str(dev))


@functools.cache
def _bf16_problem(device: str) -> str | None:
    dev = torch.device(device)
    if dev.type == "cpu" and not torch.ops.mkldnn._is_mkldnn_bf16_supported():
        return (
            f"this CPU ({torch.backends.cpu.get_cpu_capability()}) has no native bfloat16 path "
            "(oneDNN needs AVX-512 or AMX): bf16 would run emulated, slower than fp32, and the LSTM of "
            "PTACNN has no bf16 kernel here"
        )
    if dev.type == "cuda" and not torch.cuda.is_bf16_supported():
        return f"the GPU {torch.cuda.get_device_name(dev)} has no bfloat16 support"
    try:
        _probe_bf16(dev)
    except RuntimeError as e:
        return f"an operation of irlsim's networks has no bf16 kernel on {dev} ({str(e).splitlines()[0]})"
    return None


def _probe_bf16(dev: torch.device) -> None:
    """Conv1d, Linear and a 2-layer LSTM, forward and backward, under bf16 autocast on ``dev``."""
    with torch.random.fork_rng(devices=[]):  # the probe draws nothing from the caller's streams
        torch.manual_seed(0)
        conv = torch.nn.Conv1d(3, 4, 2).to(dev)
        lstm = torch.nn.LSTM(4, 4, num_layers=2, batch_first=True).to(dev)
        lin = torch.nn.Linear(4, 2).to(dev)
        x = torch.randn(2, 3, 5, device=dev)
        with torch.autocast(device_type=dev.type, dtype=torch.bfloat16):
            h = conv(x).transpose(1, 2).float()  # float32 into the LSTM, as PTACNN's inputs are
            out, _ = lstm(h)
            y = lin(out[:, -1])
        y.float().sum().backward()


def check_precision_on(device: torch.device, precision: str) -> str:
    """``precision`` when ``device`` can run it here, else a one-line IrlsimError that says why."""
    check_precision(precision)
    if precision == "bf16":
        problem = bf16_problem(device)
        if problem is not None:
            raise IrlsimError(f"--precision bf16 on {device}: {problem}: use --precision fp32")
    return precision


def resolve(spec: str, precision: str) -> torch.device:
    """``--device`` and ``--precision`` checked together before any work: the device exists and runs
    the precision (one-line IrlsimError otherwise)."""
    device = resolve_device(spec)
    check_precision_on(device, precision)
    return device


@contextmanager
def use(device: torch.device | str = "cpu", precision: str = "fp32") -> Iterator[None]:
    """Run the block's training / inference on ``device`` in ``precision``; restores the previous pair."""
    dev = device if isinstance(device, torch.device) else resolve_device(device)
    _current.append((dev, check_precision_on(dev, precision)))
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
        "(on a CPU only with AVX-512 or AMX: elsewhere it is refused)",
    )

"""What the CPU family changes (docs/RELIABILITY.md, "The machine"): a collection run as a smaller CPU would
run it (numpy's, ATen's and oneDNN's vector code limited to SSE4: NPY_DISABLE_CPU_FEATURES,
ATEN_CPU_CAPABILITY, ONEDNN_MAX_CPU_ISA) drives the same trajectories and demonstrations, byte for byte;
the policies' features agree to a few float32 ulps (numpy's vectorised math rounds differently)."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq

ROOT = Path(__file__).resolve().parents[2]


def _smaller_cpu_env() -> dict[str, str]:
    """This machine as an SSE4 one to numpy (every dispatched group off, whatever this numpy names them),
    ATen and oneDNN."""
    from numpy._core._multiarray_umath import __cpu_dispatch__

    return {
        **os.environ,
        "NPY_DISABLE_CPU_FEATURES": " ".join(__cpu_dispatch__),
        "ATEN_CPU_CAPABILITY": "default",
        "ONEDNN_MAX_CPU_ISA": "SSE41",
        "PYTHONWARNINGS": "ignore",
    }


def _collect(out: Path, env: dict[str, str] | None) -> None:
    argv = [sys.executable, "-m", "irlsim.cli", "collect", "--config", "configs/collect/tiny.toml"]
    for s in ("train_episodes=1", "validation_episodes=0", "test_episodes=0", "max_cycles=25"):
        argv += ["--set", s]
    proc = subprocess.run([*argv, "--out", str(out)], cwd=ROOT, env=env, capture_output=True, text=True)
    assert proc.returncode == 0, proc.stderr[-2000:]


def _values(column: pa.ChunkedArray) -> np.ndarray:
    """A (nested) list column's numbers as one flat float64 array."""
    arr = column.combine_chunks()
    while pa.types.is_list(arr.type) or pa.types.is_fixed_size_list(arr.type):
        arr = arr.flatten()
    return np.asarray(arr, dtype=np.float64)


def test_the_smaller_cpu_is_what_the_libraries_see():
    """The environment takes effect: numpy dispatches none of its vector groups, ATen runs its default."""
    code = (
        "import torch; from numpy._core._multiarray_umath import "
        "__cpu_dispatch__ as d, __cpu_features__ as f;"
        "print(sum(f[x] for x in d), torch.backends.cpu.get_cpu_capability())"
    )
    out = subprocess.run([sys.executable, "-c", code], env=_smaller_cpu_env(), capture_output=True, text=True)
    assert out.stdout.split() == ["0", "DEFAULT"], out.stdout + out.stderr[-500:]


def test_collection_agrees_across_vector_instruction_sets(tmp_path):
    _collect(tmp_path / "native", None)
    _collect(tmp_path / "sse4", _smaller_cpu_env())
    files = sorted(p.relative_to(tmp_path / "native") for p in (tmp_path / "native").rglob("*.parquet"))
    assert files and files == sorted(
        p.relative_to(tmp_path / "sse4") for p in (tmp_path / "sse4").rglob("*.parquet")
    )
    for rel in files:
        a, b = pq.read_table(tmp_path / "native" / rel), pq.read_table(tmp_path / "sse4" / rel)
        assert a.schema == b.schema and a.num_rows == b.num_rows > 0
        for name in a.schema.names:
            if name == "features":  # per policy: float32 math of numpy's vector code
                x, y = _values(a.column(name)), _values(b.column(name))
                np.testing.assert_allclose(y, x, rtol=2e-6, atol=1e-6 * np.abs(x).max())
            else:  # the ego's motion, the demonstrations, the other vehicles, every label: the same
                x, y = a.column(name).to_pandas(), b.column(name).to_pandas()
                assert x.equals(y), f"{rel}: {name}"  # NaN where NaN (no demonstration), else equal

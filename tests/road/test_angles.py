"""irlsim.road.angles: arc tangents within 2-3 ulp of the C library's, IEEE's signed zeros and infinities,
and the same bytes whatever vector code numpy dispatches (an AVX-512 CPU's numpy rounds its own otherwise)."""

from __future__ import annotations

import math
import os
import subprocess
import sys

import numpy as np
import pytest

from irlsim.road.angles import atan, atan2


def _wide(n: int, seed: int) -> np.ndarray:
    """Normal samples spread over 16 decades, made without numpy's transcendental functions."""
    rng = np.random.default_rng(seed)
    return rng.normal(size=n) * np.array([10.0**k for k in rng.integers(-8, 9, n).tolist()])


def test_atan_is_within_an_ulp_of_the_c_library():
    x = np.concatenate(
        [_wide(50_000, 0), [0.0, -0.0, math.inf, -math.inf, 0.66, 2.4142135623730951, 1.0, -1.0]]
    )
    ref = np.array([math.atan(v) for v in x])
    assert np.all(np.abs(atan(x) - ref) <= np.spacing(np.abs(ref)))  # 1 ulp
    assert np.array_equal(np.signbit(atan(x)), np.signbit(ref)) and np.isnan(atan(np.nan))
    x32 = x.astype(np.float32)
    ref32 = np.array([math.atan(float(v)) for v in x32])
    got32 = atan(x32)
    assert got32.dtype == np.float32
    assert np.all(np.abs(got32 - ref32) <= 3 * np.spacing(np.abs(ref32).astype(np.float32)))
    small = x32[np.abs(x32) < 0.4]  # the path without a reduction gives the reduced path's bytes
    assert np.array_equal(atan(small), atan(np.append(small, np.float32(5.0)))[:-1])


@pytest.mark.parametrize(
    "y, x",
    [(0.0, 0.0), (0.0, -0.0), (-0.0, 0.0), (-0.0, -0.0), (1.0, 0.0), (-1.0, -0.0), (0.0, -1.0)]
    + [(-0.0, -1.0), (math.inf, math.inf), (math.inf, -math.inf), (-1.0, -math.inf), (math.inf, 1.0)],
)
def test_atan2_special_values_are_ieees(y, x):
    got, ref = float(atan2(y, x)), math.atan2(y, x)
    assert got == ref and math.copysign(1.0, got) == math.copysign(1.0, ref)


def test_atan2_is_within_two_ulp_of_pi():
    y, x = _wide(50_000, 1), _wide(50_000, 2)
    ref = np.array([math.atan2(a, b) for a, b in zip(y.tolist(), x.tolist(), strict=True)])
    assert np.all(np.abs(atan2(y, x) - ref) <= 2 * np.spacing(math.pi))


def test_the_bytes_do_not_depend_on_numpys_vector_code():
    code = (
        "import hashlib, numpy as np; from irlsim.road.angles import atan, atan2;"
        "r = np.random.default_rng(3); y = r.normal(size=20000) * 50; x = r.normal(size=20000) * 50;"
        "print(hashlib.sha256(atan(y).tobytes() + atan(y.astype(np.float32)).tobytes()"
        " + atan2(y, x).tobytes()).hexdigest())"
    )
    from numpy._core._multiarray_umath import __cpu_dispatch__

    off = {**os.environ, "NPY_DISABLE_CPU_FEATURES": " ".join(__cpu_dispatch__), "PYTHONWARNINGS": "ignore"}
    native = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    scalar = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True, env=off)
    assert native.stdout and native.stdout == scalar.stdout

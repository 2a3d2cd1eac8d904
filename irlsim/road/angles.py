"""Arc tangents that round the same on every CPU.

numpy's ``arctan`` and ``arctan2`` run vector code chosen for the CPU at hand, and on an AVX-512 CPU
(Intel's SVML routines) they round differently from the code any other CPU runs: the same collection then
writes other bytes there (policy headings, the road's segment headings). :func:`atan` and :func:`atan2`
use only the four basic operations, which IEEE 754 rounds the same whatever the vector width: Cephes'
``atan`` and ``atanf`` (S. L. Moshier; the double's coefficients are also the Go standard library's
``math.Atan``), within 1 ulp of the C library's in float64 and 3 ulp in float32, vectorised over arrays.
"""

from __future__ import annotations

import numpy as np

_T3P8 = 2.41421356237309504880  # tan(3 pi / 8)
_MOREBITS = 6.123233995736765886130e-17  # pi / 2 = PIO2 + MOREBITS
_P = (
    -8.750608600031904122785e-01,
    -1.615753718733365076637e01,
    -7.500855792314704667340e01,
    -1.228866684490136173410e02,
    -6.485021904942025371773e01,
)
_Q = (
    2.485846490142306297962e01,
    1.650270098316988542046e02,
    4.328810604912902668951e02,
    4.853903996359136964868e02,
    1.945506571482613964425e02,
)
#: Cephes' atanf: the polynomial on [0, tan(pi/8)] and its reduction thresholds, in float32
_PF = tuple(np.float32(c) for c in (8.05374449538e-2, -1.38776856032e-1, 1.99777106478e-1, -3.33329491539e-1))
_F32 = np.float32


def atan(x: np.ndarray | float) -> np.ndarray:
    """arctan(x) [rad] elementwise, the same bytes on every CPU (NaN stays NaN): in float32 for a float32
    array (:func:`atan32`), else in float64."""
    x = np.asarray(x)
    if x.dtype == np.float32:
        return atan32(x)
    x = x.astype(np.float64, copy=False)
    ax = np.abs(x)
    big, mid = ax > _T3P8, (ax > 0.66) & (ax <= _T3P8)
    with np.errstate(divide="ignore", invalid="ignore"):
        # the argument reduced to [0, 0.66]: -1/x beyond tan(3 pi/8), (x - 1)/(x + 1) from 0.66
        z = np.where(big, -1.0 / ax, np.where(mid, (ax - 1.0) / (ax + 1.0), ax))
    zz = z * z
    p = (((_P[0] * zz + _P[1]) * zz + _P[2]) * zz + _P[3]) * zz + _P[4]
    q = ((((zz + _Q[0]) * zz + _Q[1]) * zz + _Q[2]) * zz + _Q[3]) * zz + _Q[4]
    r = z * (zz * p / q) + z
    base = np.where(big, np.pi / 2, np.where(mid, np.pi / 4, 0.0))
    more = np.where(big, _MOREBITS, np.where(mid, 0.5 * _MOREBITS, 0.0))
    return np.copysign(base + (r + more), x)


def atan32(x: np.ndarray) -> np.ndarray:
    """arctan(x) [rad] of a float32 array in float32 (Cephes' ``atanf``, within 3 ulp; numpy's own, within
    2, rounds differently on an AVX-512 CPU)."""
    ax = np.abs(x)
    if ax.size and ax.max() <= _F32(0.4142135623730950):  # no reduction (a policy heading to its lane)
        return _atanf_poly(x)
    big, mid = ax > _F32(2.414213562373095), (ax > _F32(0.4142135623730950)) & (ax <= _F32(2.414213562373095))
    with np.errstate(divide="ignore", invalid="ignore"):
        z = np.where(big, _F32(-1.0) / ax, np.where(mid, (ax - _F32(1.0)) / (ax + _F32(1.0)), ax))
    r = _atanf_poly(z)
    base = np.where(big, _F32(np.pi / 2), np.where(mid, _F32(np.pi / 4), _F32(0.0)))
    return np.copysign(base + r, x)


def _atanf_poly(z: np.ndarray) -> np.ndarray:
    """Cephes' atanf on the reduced argument, |z| <= tan(pi/8), in float32."""
    zz = z * z
    return (((_PF[0] * zz + _PF[1]) * zz + _PF[2]) * zz + _PF[3]) * zz * z + z


def atan2(y: np.ndarray | float, x: np.ndarray | float) -> np.ndarray:
    """arctan2(y, x) [rad] in (-pi, pi], float64, elementwise, the same bytes on every CPU; signed zeros
    as IEEE 754's atan2 (atan2(+0, -0) = pi, atan2(-0, +0) = -0)."""
    y, x = np.broadcast_arrays(np.asarray(y, dtype=np.float64), np.asarray(x, dtype=np.float64))
    with np.errstate(divide="ignore", invalid="ignore"):
        ratio = y / x
    both_zero = (y == 0.0) & (x == 0.0)
    both_inf = np.isinf(y) & np.isinf(x)
    ratio = np.where(both_zero, np.copysign(0.0, y), np.where(both_inf, np.copysign(1.0, y * x), ratio))
    r = atan(ratio)
    # x < 0 (-0 included): the other half plane, towards y's side
    return np.where(np.signbit(x), r + np.copysign(np.pi, y), r)

"""How a planner turns a reward into one policy: the most likely policy, or the fit's expectation.

A learned reward is a maximum-entropy model: it puts p(pi) ~ exp(V(pi)), V = -theta^T f, on the cycle's
policies, and what maximum-entropy IRL fits to the demonstrations is the *expected* feature cost under
p, not the cost of the single most likely policy. The planner has to execute one policy, and the two
choices differ where a decision is spread over many policies:

- ``argmax``: the most likely policy (the paper's planner; the default everywhere).
- ``expected``: the decision the distribution expects, then the policy it expects within it. The
  maneuver of a policy is where it ends sideways (its last control point's lateral offset to the ego,
  to 0.1 m: the lane it heads for); a lane change is a maneuver ending over ``SIDEWAYS`` m to either
  side. The maneuver chosen is the one with the largest probability mass, a lane change's mass first
  multiplied by ``lane_change_bias``; within it, among the policies with the lateral profile of its most
  likely one, the policy whose progress profile (the control points' progress) is closest (RMS) to
  the maneuver's expected progress profile under p.
- ``maneuver``: the decision the distribution expects (as ``expected``, with the same bias), then the
  most likely policy within it: the argmax wherever the argmax's maneuver is the one chosen.

The bias is set so that the choice changes lanes as often as the distribution expects on the states the
reward was trained on (:func:`calibrate_lane_change_bias`, closed form): the argmax changes lanes far
less often than the fit expects, because a lane change is one decision spread over many policies (the
style study, docs/results/styles.md). Both choices are vectorised over the policies; the calibration
over the cycles.
"""

from __future__ import annotations

import numpy as np

#: [m] a maneuver ending farther sideways than this changes lanes (the planner's swerves reach 1.6 m
#: and return; its lane changes end a lane width away)
SIDEWAYS = 2.0
#: the choices a planner can make from a reward
CHOICES = ("argmax", "expected", "maneuver")


def _distribution(value: np.ndarray, allowed: np.ndarray | None) -> np.ndarray:
    """p ~ exp(value) over the allowed policies (0 elsewhere); [N] float64."""
    v = np.asarray(value, dtype=np.float64)
    if allowed is not None:
        v = np.where(allowed, v, -np.inf)
    p = np.exp(v - v.max())
    return p / p.sum()


def maneuver_masses(
    value: np.ndarray, control_points: np.ndarray, allowed: np.ndarray | None = None
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """(p [N], maneuver of every policy [N] int, the maneuvers' final offsets [M] [m], their masses [M])
    of one cycle: ``value`` [N] (V, higher is better), ``control_points`` [N, K, 3]."""
    p = _distribution(value, allowed)
    end = np.round(np.asarray(control_points)[:, -1, 0].astype(np.float64), 1)
    offsets, which = np.unique(end, return_inverse=True)
    return p, which, offsets, np.bincount(which, weights=p, minlength=len(offsets))


def expected_choice(
    value: np.ndarray,
    control_points: np.ndarray,
    lane_change_bias: float = 1.0,
    allowed: np.ndarray | None = None,
    within: str = "expected",
) -> int:
    """The ``expected`` choice (module docstring) over one cycle's policies; ``allowed`` [N] bool limits
    it to some (None: all; at least one must be allowed); ``within="argmax"``: the ``maneuver`` choice
    (the chosen maneuver's most likely policy)."""
    cp = np.asarray(control_points)
    p, which, offsets, mass = maneuver_masses(value, cp, allowed)
    score = mass * np.where(np.abs(offsets) > SIDEWAYS, lane_change_bias, 1.0)
    members = (which == int(np.argmax(score))) & (p > 0)
    v = np.where(members, np.asarray(value, dtype=np.float64), -np.inf)
    best = int(np.argmax(v))
    if within == "argmax":
        return best
    q = np.where(members, p, 0.0)
    profile = q @ cp[:, :, 2].astype(np.float64) / q.sum()  # [K] the maneuver's expected progress profile
    same = members & np.all(cp[:, :, 0] == cp[best, :, 0], axis=1)
    miss = np.sqrt(np.mean((cp[:, :, 2] - profile) ** 2, axis=1))
    return int(np.argmin(np.where(same, miss, np.inf)))


def change_ratio(value: np.ndarray, control_points: np.ndarray) -> tuple[float, float]:
    """(the bias above which the ``expected`` choice changes lanes in this cycle: the largest keeping
    maneuver's mass over the largest lane change's, inf when there is none; the distribution's mass of
    lane changes)."""
    _, _, offsets, mass = maneuver_masses(value, control_points)
    change = np.abs(offsets) > SIDEWAYS
    keep_mass = float(mass[~change].max(initial=0.0))
    change_mass = float(mass[change].max(initial=0.0))
    ratio = keep_mass / change_mass if change_mass > 0 else np.inf
    return ratio, float(mass[change].sum())


def calibrate_lane_change_bias(ratios: np.ndarray, change_mass: np.ndarray) -> float:
    """The lane-change bias with which the ``expected`` choice changes lanes in the share of cycles the
    distribution expects: ``ratios`` [C] and ``change_mass`` [C] are :func:`change_ratio` of C cycles (the
    states the reward was trained on). The choice changes lanes in cycle c iff bias > ratios[c], so the
    bias is the quantile of the ratios at the expected share (closed form; at least 1: the bias never
    holds a lane change back)."""
    ratios = np.asarray(ratios, dtype=np.float64)
    if ratios.size == 0:
        raise ValueError("no cycles to calibrate the lane-change bias on")
    finite = np.sort(ratios[np.isfinite(ratios)])  # cycles with a lane change to choose
    k = min(int(np.floor(float(np.mean(change_mass)) * len(ratios))), len(finite))  # cycles that should
    if k == 0:
        return 1.0
    return float(max(finite[k - 1] * (1 + 1e-9), 1.0))  # the k cycles with the smallest ratios change

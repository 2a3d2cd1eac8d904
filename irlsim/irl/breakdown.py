"""Table I's breakdowns: OPD and ED per situation, and reward stability, per row.

``CycleContext`` carries what the breakdowns need beyond the split's tensors, read from the cycles table
(situation, ego s / d, time) and aligned with the split's rows. ``row_breakdown`` turns one row's
per-cycle metrics (and, where the row has them, its thetas or chosen policies) into the figures that
``irlsim evaluate`` adds to a Table-I row; ``breakdown_markdown`` renders them.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np
import torch

from irlsim.irl.objectives import policy_values
from irlsim.irl.stability import plan_change, stability_summary, theta_change

#: cycles before / after a situation switch counted as "around" it
SWITCH_WINDOW = 2


@dataclass(frozen=True)
class CycleContext:
    """Per-cycle data of a split beyond its tensors, rows aligned with the split: [C] each."""

    situation: np.ndarray  # int8 codes (irlsim.data.situations), -1 = unlabelled
    ego_s: np.ndarray  # [m] unwrapped
    ego_d: np.ndarray  # [m]
    t: np.ndarray  # [s]
    horizon: float  # [s] planning horizon (control points at horizon * k / K)
    names: tuple[str, ...] = ()  # situation code -> name (irlsim.data.situations.SITUATION_NAMES)
    scenario: np.ndarray | None = None  # [C] scenario names; None: no breakdown by scenario
    demonstrator: np.ndarray | None = None  # [C] demonstrator identities; None: no breakdown by them

    @staticmethod
    def from_cycles(cycles: Any, split: Any, horizon: float, names: tuple[str, ...]) -> CycleContext:
        """From a cycles DataFrame (``Dataset.read_cycles``) in (episode, cycle) order; checks alignment."""
        ep = np.asarray(cycles["episode"]).astype(np.int64)
        cy = np.asarray(cycles["cycle"]).astype(np.int64)
        c = split.features.shape[0]
        if (
            len(ep) < c
            or (ep[:c] != np.asarray(split.episode)).any()
            or (cy[:c] != np.asarray(split.cycle)).any()
        ):
            raise ValueError("cycles table and split tensors are not aligned (rebuild the dataset cache)")
        sit = np.asarray(cycles["situation"])[:c] if "situation" in cycles else np.full(c, -1)
        return CycleContext(
            situation=sit.astype(np.int64),
            ego_s=np.asarray(cycles["ego_s"], np.float64)[:c],
            ego_d=np.asarray(cycles["ego_d"], np.float64)[:c],
            t=np.asarray(cycles["t"], np.float64)[:c],
            horizon=float(horizon),
            names=tuple(names),
        )


def argmax_policies(thetas: np.ndarray, split: Any, chunk: int = 256) -> np.ndarray:
    """[C] index of argmax V = -theta^T f per cycle (ties: lowest index, as OPD)."""
    c = split.features.shape[0]
    out = np.zeros(c, dtype=np.int64)
    with torch.no_grad():
        for start in range(0, c, chunk):
            sl = slice(start, min(start + chunk, c))
            v = policy_values(
                torch.as_tensor(np.asarray(thetas[sl]), dtype=torch.float64),
                torch.tensor(np.asarray(split.features[sl]), dtype=torch.float64),
            )
            out[sl] = v.argmax(-1).numpy()
    return out


def per_situation(
    metrics: dict[str, np.ndarray], situation: np.ndarray, names: tuple[str, ...]
) -> dict[str, dict[str, float]]:
    """{situation name: {'opd', 'ed', 'cycles'}} over cycles with a demonstration (code i = names[i])."""
    out = {}
    valid = metrics["valid"]
    for code, name in enumerate(names):
        m = valid & (situation == code)
        n = int(m.sum())
        out[name] = {
            "opd": float(metrics["opd"][m].mean()) if n else float("nan"),
            "ed": float(metrics["ed"][m].mean()) if n else float("nan"),
            "cycles": n,
        }
    return out


def per_scenario(metrics: dict[str, np.ndarray], scenario: np.ndarray) -> dict[str, dict[str, float]]:
    """{scenario name: {'opd', 'ed', 'cycles'}} over cycles with a demonstration, names in order of
    first appearance (the split's episode order)."""
    out = {}
    valid = metrics["valid"]
    for name in dict.fromkeys(np.asarray(scenario).tolist()):
        m = valid & (scenario == name)
        n = int(m.sum())
        out[str(name)] = {
            "opd": float(metrics["opd"][m].mean()) if n else float("nan"),
            "ed": float(metrics["ed"][m].mean()) if n else float("nan"),
            "cycles": n,
        }
    return out


def row_breakdown(
    metrics: dict[str, np.ndarray],
    split: Any,
    ctx: CycleContext,
    thetas: np.ndarray | None = None,
    chosen: np.ndarray | None = None,
) -> dict[str, Any]:
    """{'situations': per_situation(...), 'stability': stability_summary(...)} of one row, and
    'scenarios': per_scenario(...) when ``ctx`` has the cycles' scenarios. ``thetas``
    [C, 15] (None: a row without a reward, e.g. 'executed'); ``chosen`` [C] policy per cycle (default:
    argmax V of ``thetas``; None for both: no plan stability, e.g. 'random policy')."""
    episode = np.asarray(split.episode)
    bad = np.zeros(split.features.shape[0], dtype=bool)  # cycles without a theta (oracle: no demonstration)
    if thetas is not None:
        bad = ~np.isfinite(thetas).all(1)
    if chosen is None and thetas is not None:
        chosen = argmax_policies(np.nan_to_num(thetas), split)
    plan = (
        plan_change(chosen, split.control_points, ctx.ego_s, ctx.ego_d, ctx.t, episode, ctx.horizon)
        if chosen is not None
        else np.full(split.features.shape[0], np.nan)
    )
    plan[bad | np.concatenate([[False], bad[:-1]])] = np.nan
    theta = theta_change(thetas, episode) if thetas is not None else None
    sit = ctx.situation if (ctx.situation >= 0).all() else None
    out = {
        "situations": per_situation(metrics, ctx.situation, ctx.names),
        "stability": stability_summary(theta, plan, sit, episode, SWITCH_WINDOW),
    }
    if ctx.scenario is not None:
        out["scenarios"] = per_scenario(metrics, ctx.scenario)
    if ctx.demonstrator is not None:
        out["demonstrators"] = per_scenario(metrics, ctx.demonstrator)
    return out


def _f(v: Any, digits: int = 3) -> str:
    return "–" if v is None or (isinstance(v, float) and math.isnan(v)) else f"{v:.{digits}f}"


def _scenario_lines(rows: list[dict[str, Any]], key: str = "scenarios", what: str = "scenario") -> list[str]:
    """The per-scenario table (Table I by scenario) of rows that carry a ``key`` entry (per
    demonstrator: 'demonstrators', 'demonstrator')."""
    rows = [r for r in rows if key in r]
    if not rows:
        return []
    counts = rows[0][key]
    head = " | ".join(f"{n} ({counts[n]['cycles']})" for n in counts)
    lines = [f"## OPD / ED per {what} [m]", "", f"| model | {head} |", "|---|" + "---|" * len(counts)]
    for r in rows:
        s = r[key]
        lines.append(
            f"| {r['model']} | " + " | ".join(f"{_f(s[n]['opd'])} / {_f(s[n]['ed'])}" for n in counts) + " |"
        )
    return [
        *lines,
        "",
        f"OPD / ED per {what} the cycles were collected {'on' if what == 'scenario' else 'with'} (cycles "
        "with a demonstration in brackets).",
        "",
    ]


def breakdown_markdown(rows: list[dict[str, Any]]) -> str:
    """The per-situation and stability tables of rows that carry a 'situations' / 'stability' entry."""
    rows = [r for r in rows if "situations" in r]
    if not rows:
        return ""
    counts = rows[0]["situations"]
    names = [n for n in counts if counts[n]["cycles"] > 0]
    head = " | ".join(f"{n} ({counts[n]['cycles']})" for n in names)
    lines = [
        "## OPD / ED per situation [m]",
        "",
        f"| model | {head} |",
        "|---|" + "---|" * len(names),
    ]
    for r in rows:
        s = r["situations"]
        lines.append(
            f"| {r['model']} | " + " | ".join(f"{_f(s[n]['opd'])} / {_f(s[n]['ed'])}" for n in names) + " |"
        )
    lines += [
        "",
        "OPD / ED per situation label (irlsim.data.situations; cycles with a demonstration in brackets).",
        "",
        *_scenario_lines(rows),
        *_scenario_lines(rows, "demonstrators", "demonstrator"),
        "## Reward stability",
        "",
        "| model | theta change | theta change at switches | plan change [m] | plan change at switches [m] |",
        "|---|---|---|---|---|",
    ]
    for r in rows:
        st = r["stability"]
        lines.append(
            f"| {r['model']} | {_f(st['theta_change'])} | {_f(st['theta_change_switch'])} | "
            f"{_f(st['plan_change'])} | {_f(st['plan_change_switch'])} |"
        )
    lines += [
        "",
        "theta change: mean |theta_{t+1} - theta_t| / |theta_t| between consecutive cycles; plan change: "
        "mean distance over their common time span between the policies chosen at t+1 and t "
        "(irlsim.irl.stability); "
        f"'at switches': pairs within {SWITCH_WINDOW} cycles of a situation change.",
        "",
    ]
    temporal = [r for r in rows if r.get("temporal")]
    if temporal:
        lines += [
            "## Temporal attention",
            "",
            "| model | newest-entry weight | at switches | weight shift (L1) | at switches |",
            "|---|---|---|---|---|",
        ]
        for r in temporal:
            w = r["temporal"]
            lines.append(
                f"| {r['model']} | {_f(w['newest_weight'])} | {_f(w['newest_weight_switch'])} | "
                f"{_f(w['weight_shift'])} | {_f(w['weight_shift_switch'])} |"
            )
        lines += [
            "",
            "newest-entry weight: mean softmax weight of the current cycle in the H-cycle history (1 = the "
            "history is ignored, 1/H = the H-mean); weight shift: mean L1 change of the weights between "
            "consecutive cycles.",
            "",
        ]
    return "\n".join(lines)

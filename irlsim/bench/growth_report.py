"""``irlsim bench --growth`` as a library: :func:`run_growth` measures the curves of
:mod:`irlsim.bench.growth`, fits each and writes ``growth.json``, ``growth.md`` (one table: sizes, costs,
log-log slopes) and ``growth.png`` (every curve; one ``growth_<curve>.png`` each too) into the out folder.

The fit of a curve: the least-squares slope of log(cost) against log(size) over the points with a
positive size (1: the cost grows linearly, 2: quadratically, 0: not at all), the same slope between
its last two points (where an affine cost a + b x tends to 1), and the affine fit a + b x itself with
its R^2 (how much is a fixed part, how much a cost per unit).
"""

from __future__ import annotations

import math
import platform
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from irlsim.bench.growth import (
    QUICK,
    Curve,
    GrowthSizes,
    Progress,
    collect_curves,
    disk_curves,
    planner_curves,
)
from irlsim.bench.growth_train import training_curves
from irlsim.errors import IrlsimError
from irlsim.outputs import check_output_dir
from irlsim.road.scenario import DEFAULT_SCENARIO
from irlsim.utils import atomic_write_text, write_json


@dataclass(frozen=True)
class GrowthRun:
    """One ``irlsim bench --growth``: where the results go, full or quick sizes, the seed, the road."""

    out: Path = Path("bench")
    quick: bool = False
    seed: int = 0
    scenario: str = DEFAULT_SCENARIO
    """the road of the planner's policies and vehicles curves"""

    @property
    def sizes(self) -> GrowthSizes:
        """The sizes of the run: :data:`~irlsim.bench.growth.QUICK` or the full ones."""
        return QUICK if self.quick else GrowthSizes()


def measure_growth(run: GrowthRun, say: Progress) -> list[Curve]:
    """Every curve, in the order of the table (training before inference: inference loads its model)."""
    sizes = run.sizes
    curves = planner_curves(sizes, run.seed, run.scenario, say)
    curves += collect_curves(sizes, run.seed, say)
    curves += disk_curves(sizes, run.seed, say)
    curves += training_curves(sizes, run.seed, say)
    return curves


#: log-log slope bounds of the words in the table
FLAT, LINEAR_LOW, LINEAR_HIGH = 0.15, 0.85, 1.15


def growth_word(slope: float) -> str:
    """How a cost with this log-log slope grows: falls, flat, sub-linear, linear or super-linear."""
    if not math.isfinite(slope):
        return "unknown"
    if slope < -FLAT:
        return "falls"
    if slope < FLAT:
        return "flat"
    if slope < LINEAR_LOW:
        return "sub-linear"
    return "linear" if slope <= LINEAR_HIGH else "super-linear"


def fit_curve(x: list[float], y: list[float]) -> dict[str, Any]:
    """The log-log slope (all points of positive size and cost; the last two), and the affine fit."""
    xa, ya = np.asarray(x, dtype=float), np.asarray(y, dtype=float)
    keep = (xa > 0) & (ya > 0) & np.isfinite(ya)
    lx, ly = np.log(xa[keep]), np.log(ya[keep])
    slope = last = math.nan
    if keep.sum() >= 2:
        slope = float(np.polyfit(lx, ly, 1)[0])
        last = float((ly[-1] - ly[-2]) / (lx[-1] - lx[-2]))
    per_unit = fixed = r2 = math.nan
    if len(xa) >= 2 and np.isfinite(ya).all():
        per_unit, fixed = (float(v) for v in np.polyfit(xa, ya, 1))
        resid = ya - (fixed + per_unit * xa)
        total = float(((ya - ya.mean()) ** 2).sum())
        r2 = 1.0 - float((resid**2).sum()) / total if total > 0 else 1.0
    return {
        "loglog_slope": round(slope, 3),
        "last_step_slope": round(last, 3),
        "growth": growth_word(slope),
        "fixed": float(f"{fixed:.4g}"),
        "per_unit": float(f"{per_unit:.4g}"),
        "affine_r2": round(r2, 4),
    }


def _num(v: float) -> str:
    if not math.isfinite(v):
        return "n/a"
    if abs(v) >= 100:
        return f"{v:,.0f}"
    return f"{v:.3g}"


#: the singular of each size's name
SINGULAR = {
    "policies": "policy",
    "vehicles": "vehicle",
    "lanes": "lane",
    "workers": "worker",
    "cycles": "cycle",
}


def _affine(c: Curve, fit: dict[str, Any]) -> str:
    """'a + b unit per [1,000] sizes (R^2 r)': per 1,000 where the sizes reach 2,000."""
    per = 1000 if max(c.x) >= 2000 else 1
    what = c.x_label if per > 1 else SINGULAR.get(c.x_label, c.x_label)
    b = fit["per_unit"] * per
    sign = "-" if b < 0 else "+"
    return (
        f"{_num(fit['fixed'])} {sign} {_num(abs(b))} {c.unit} per {'1,000 ' if per > 1 else ''}{what} "
        f"(R² {fit['affine_r2']:.3f})"
    )


def markdown(curves: list[Curve], fits: dict[str, dict[str, Any]], header: str) -> str:
    lines = [
        "# How each cost grows (`irlsim bench --growth`)",
        "",
        header,
        "",
        "Slope: least-squares slope of log(cost) against log(size) (sizes > 0); 1 is linear, below "
        f"{LINEAR_LOW} sub-linear (below {FLAT}: flat), above {LINEAR_HIGH} super-linear. Last step: the "
        "same between the two largest sizes. Affine fit: fixed part + cost per unit, over all points.",
        "",
        "| curve | setting | size: cost | slope | last step | growth | affine fit |",
        "|---|---|---|---|---|---|---|",
    ]
    for c in curves:
        f = fits[c.name]
        points = ", ".join(f"{_num(x)}: {_num(y)}" for x, y in zip(c.x, c.y, strict=True))
        lines.append(
            f"| {c.title} [{c.unit}] | {c.setting} | {points} | {f['loglog_slope']:.2f} | "
            f"{f['last_step_slope']:.2f} | {f['growth']} | {_affine(c, f)} |"
        )
    return "\n".join(lines) + "\n"


def _draw(ax: Any, c: Curve, fit: dict[str, Any]) -> None:
    from matplotlib.ticker import FuncFormatter, LogLocator, NullFormatter

    x, y = np.asarray(c.x), np.asarray(c.y)
    ax.plot(x, y, "o-", color="tab:blue")
    if (x > 0).all() and (y > 0).all():
        ax.set_xscale("log")
        if y.max() > 2 * y.min():  # a flat curve keeps a linear y axis (a log one would show no tick)
            ax.set_yscale("log")
            ax.yaxis.set_major_locator(LogLocator(subs=(1.0, 2.0, 5.0)))
        if math.isfinite(fit["loglog_slope"]):  # the fitted power law through the points' centre
            k = np.exp(np.log(y).mean() - fit["loglog_slope"] * np.log(x).mean())
            ax.plot(x, k * x ** fit["loglog_slope"], "--", color="tab:gray", lw=1)
    if ax.get_yscale() == "linear":
        ax.set_ylim(bottom=0)  # from zero, so that a flat curve looks flat
    # plain numbers: the measured sizes on x, a few round values on y
    ax.set_xticks(x)
    plain = FuncFormatter(lambda v, _: f"{v:g}")
    for axis in (ax.xaxis, ax.yaxis):
        axis.set_major_formatter(plain)
        axis.set_minor_formatter(NullFormatter())
    ax.set_title(f"{c.title}\nslope {fit['loglog_slope']:.2f} ({fit['growth']})", fontsize=9)
    ax.set_xlabel(c.x_label, fontsize=8)
    ax.set_ylabel(c.unit, fontsize=8)
    ax.tick_params(labelsize=7)
    ax.grid(True, which="both", alpha=0.3)


def plot(curves: list[Curve], fits: dict[str, dict[str, Any]], out: Path) -> list[Path]:
    """growth.png (every curve; log-log where every size is positive) and growth_<curve>.png each."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    cols = 4
    rows = math.ceil(len(curves) / cols)
    fig, axes = plt.subplots(rows, cols, figsize=(4 * cols, 3.3 * rows), squeeze=False)
    for ax, c in zip(axes.flat, curves, strict=False):
        _draw(ax, c, fits[c.name])
    for ax in list(axes.flat)[len(curves) :]:
        ax.axis("off")
    fig.tight_layout()
    paths = [out / "growth.png"]
    fig.savefig(paths[0], dpi=80)
    plt.close(fig)
    for c in curves:
        fig, ax = plt.subplots(figsize=(4.5, 3.5))
        _draw(ax, c, fits[c.name])
        fig.tight_layout()
        paths.append(out / f"growth_{c.name}.png")
        fig.savefig(paths[-1], dpi=80)
        plt.close(fig)
    return paths


def n_points(s: GrowthSizes) -> int:
    """How many points the sizes measure (the progress lines count them)."""
    return (
        2 * len(s.policies) + len(s.vehicles) + len(s.lanes) + len(s.workers) + len(s.disk_policies)
        + len(s.train_cycles) + len(s.train_policies)
    )  # fmt: skip


def check_growth(run: GrowthRun) -> None:
    """One-line refusals before any work: the out folder, the road."""
    from irlsim.road.scenario import scenario_path

    check_output_dir(run.out, "--out")
    scenario_path(run.scenario)
    if run.seed < 0:
        raise IrlsimError(f"--seed must be >= 0, got {run.seed}")


def run_growth(run: GrowthRun) -> Path:
    """Measure every curve, fit it and write growth.json, growth.md and the PNGs into ``run.out``;
    returns growth.md's path."""
    check_growth(run)
    total = n_points(run.sizes)
    t0 = time.perf_counter()
    done = 0

    def say(msg: str) -> None:
        nonlocal done
        done += 1
        print(f"growth [{done}/{total}, {time.perf_counter() - t0:.0f} s] {msg}", flush=True)

    print(f"growth: {total} points ({'quick' if run.quick else 'full'} sizes) -> {run.out}", flush=True)
    curves = measure_growth(run, say)
    fits = {c.name: fit_curve(c.x, c.y) for c in curves}
    wall = time.perf_counter() - t0
    header = (
        f"Machine: {platform.machine()}, {platform.processor() or 'cpu'}, Python "
        f"{platform.python_version()}; {'quick' if run.quick else 'full'} sizes, seed {run.seed}; "
        f"{wall:.0f} s in all. Planner, collection workers and inference: one thread each; training: "
        f"{run.sizes.train_threads}."
    )
    run.out.mkdir(parents=True, exist_ok=True)
    write_json(
        run.out / "growth.json",
        {
            "what": "how each cost grows with its size (irlsim bench --growth)",
            "quick": run.quick,
            "seed": run.seed,
            "wall_s": round(wall, 1),
            "curves": {c.name: {**vars(c), "fit": fits[c.name]} for c in curves},
        },
    )
    atomic_write_text(run.out / "growth.md", markdown(curves, fits, header))
    pngs = plot(curves, fits, run.out)
    more = f"and {len(pngs) - 1} more PNGs"
    print(f"wrote {run.out / 'growth.json'}, {run.out / 'growth.md'}, {pngs[0]} {more}", flush=True)
    return run.out / "growth.md"

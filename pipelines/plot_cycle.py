"""``irlsim plot-cycle``: drive the expert in SUMO to time T and draw that cycle's policies as PNG."""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

from irlsim import FEATURE_NAMES
from irlsim.config import float_in, int_in, load_config
from irlsim.errors import IrlsimError
from irlsim.planner.expert import THETA_EXPERT, make_expert_driver
from irlsim.road import load_road
from irlsim.road.scenario import Scenarios
from irlsim.sim.config import EpisodeConfig
from irlsim.sim.simulation import MAX_SEED, Simulation
from irlsim.utils import atomic_path, check_output_file
from irlsim.viz.cycle import draw_cycle

HELP = "draw one planning cycle's policies coloured by value under a theta (expert driving in SUMO)"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--seed", type=int_in(0, MAX_SEED), default=0, help="episode seed (>= 0)")
    parser.add_argument(
        "--time", type=float_in(0), default=20.0, help="simulation time of the cycle to draw [s]"
    )
    parser.add_argument("--out", type=Path, default=Path("cycle.png"), help="output PNG")
    parser.add_argument(
        "--theta",
        default="expert",
        help="'expert' or 15 comma-separated weights (FEATURE_NAMES order) to colour by",
    )
    parser.add_argument(
        "--vehicles", type=int_in(0, 15), default=None, help="background vehicles, 0..15 (default 15)"
    )


def run(args: argparse.Namespace) -> int:
    import matplotlib  # lazy: pyplot costs about a second at start-up; only this command needs it

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    # validate everything before driving, so a bad option fails at once and writes nothing
    if args.seed < 0 or args.time < 0:
        raise IrlsimError("--seed and --time must be >= 0")
    if args.seed > MAX_SEED:
        raise IrlsimError(f"--seed must be <= {MAX_SEED} (SUMO's largest seed), got {args.seed}")
    check_output_file(args.out, "--out", "cycle.png")
    if args.theta == "expert":
        theta = THETA_EXPERT
    else:
        try:
            theta = np.array([float(v) for v in args.theta.split(",")])
        except ValueError:
            raise IrlsimError("--theta must be 'expert' or 15 comma-separated numbers") from None
        if theta.shape != (len(FEATURE_NAMES),):
            raise IrlsimError(f"--theta needs {len(FEATURE_NAMES)} weights, got {theta.size}")
    overrides = {"laps": 3} if args.vehicles is None else {"laps": 3, "n_vehicles": args.vehicles}
    scenarios = Scenarios()  # the road's file read once: for its [defaults] and the road
    cfg = load_config(EpisodeConfig, None, overrides, scenarios=scenarios)
    road = load_road(scenario=scenarios(cfg.name))
    drv = make_expert_driver(road, cfg)
    with Simulation(road, cfg) as sim:
        obs = sim.reset(args.seed)
        while obs.ego.t + 1e-9 < args.time and not sim.done:
            sim.execute(drv.plan(obs))
            obs = sim.observe()
        drv.plan(obs)
    ps, idx = drv.last_policy_set, drv.last_index
    assert ps is not None
    fig, ax = plt.subplots(figsize=(12, 6))
    draw_cycle(ax, road, ps, ps.value(theta), chosen=idx, vehicles=obs.vehicles, horizon=cfg.horizon)
    ax.set_title(
        f"seed {args.seed}, t = {obs.ego.t:.1f} s: {ps.n_policies} policies coloured by value "
        f"(green high, red low), executed in black"
    )
    args.out.parent.mkdir(parents=True, exist_ok=True)
    with atomic_path(args.out) as tmp:
        fig.savefig(tmp, dpi=120, format="png", bbox_inches="tight")
    plt.close(fig)
    print(f"wrote {args.out}")
    return 0

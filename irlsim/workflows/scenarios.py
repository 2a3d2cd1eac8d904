"""Scenario commands' work: the acceptance of one scenario (``irlsim scenario check``:
:func:`check_scenario_run` with :class:`CheckRun`) and generated networks for sweeps
(``irlsim scenario generate``: :func:`generate_networks` with :class:`GenerateRun`). The sweep itself is
:mod:`irlsim.workflows.sweep`.
"""

from __future__ import annotations

import json
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

from irlsim.config import MAX_SEED
from irlsim.errors import IrlsimError
from irlsim.outputs import check_output_dir
from irlsim.road.generate import build_network, network_params
from irlsim.road.scenario import Scenarios
from irlsim.rollout.acceptance import MISSION_MIN, SPEED_TOLERANCE, Acceptance, check_scenario
from irlsim.sim.config import scenario_config
from irlsim.utils import atomic_write_text, owned_output, progress, write_json

# ------------------------------------------------------------------------------------------ check


@dataclass(frozen=True)
class CheckRun:
    """The acceptance of one scenario: what ``irlsim scenario check`` parses its arguments into."""

    scenario: str
    """a shipped name or a scenario.toml path (or its folder)"""
    out: Path | None = None
    """output folder: check.md, check.json (None: runs/check/<the scenario's name>)"""
    episodes: int = 10
    """episodes per driver (the expert, SUMO's driver), on the same seeds"""
    seed: int = 1000
    """episode i uses seed ``seed + i``"""
    max_time: float | None = None
    """[s] simulated time of an episode at most (None: the scenario's own, 600 s unless it says)"""


CHECK_COLUMNS = (
    "| scenario | seeds | collisions | exits | red crossed | stops | mission | expert km/h | SUMO's km/h "
    "| ratio | verdict |"
)


def check_markdown(acc: Acceptance, name: str) -> str:
    """The acceptance as the Markdown table of docs/results/scenarios.md, with the verdict."""
    e, s = acc.expert, acc.sumo
    seeds = f"{acc.seeds[0]}-{acc.seeds[-1]}" if len(acc.seeds) > 1 else str(acc.seeds[0])
    stops = f"{int(e['stops_compliant'])}/{int(e['stops_passed'])}" if e["stops_passed"] else "-"
    verdict = "meets the bar" if not acc.failures else "misses: " + ", ".join(acc.failures)
    row = (
        f"| {name} | {seeds} | {int(e['collisions'])} | {int(e['exits'])} | {int(e['red_crossings'])} "
        f"| {stops} | {int(e['checkpoints_in_lane'])}/{int(e['checkpoints_passed'])} "
        f"| {e['mean_speed_kmh']:.1f} | {s['mean_speed_kmh']:.1f} | {acc.speed_ratio:.2f} | {verdict} |"
    )
    bar = (
        f"The bar: no collision, no exit, no red light crossed, a full stop at every stop sign, at least "
        f"{100 * MISSION_MIN:.0f} % of the checkpoints in lane, a mean speed within "
        f"{100 * SPEED_TOLERANCE:.0f} % of SUMO's driver's."
    )
    return "\n".join([CHECK_COLUMNS, "|---" * 11 + "|", row, "", bar]) + "\n"


def check_scenario_run(run: CheckRun) -> Acceptance:
    """The expert and SUMO's driver on the same seeds of the scenario (:mod:`irlsim.rollout.acceptance`);
    writes ``check.md`` and ``check.json`` into ``run.out``, prints the table and where it wrote.
    One-line errors before any work for an unknown scenario, bad numbers or an unusable folder."""
    if run.episodes < 1:
        raise IrlsimError(f"--episodes must be >= 1, got {run.episodes}")
    if not 0 <= run.seed <= MAX_SEED - run.episodes:
        raise IrlsimError(f"--seed must be in 0..{MAX_SEED - run.episodes}, got {run.seed}")
    if run.max_time is not None and not run.max_time > 0:
        raise IrlsimError(f"--max-time must be > 0 s, got {run.max_time}")
    scenarios = Scenarios()  # the scenario's file read once: its road, its [defaults], the episodes
    scn = scenarios(run.scenario)
    out = run.out if run.out is not None else Path("runs/check") / scn.name
    check_output_dir(out, "--out")
    overrides: dict[str, Any] = {} if run.max_time is None else {"max_time": run.max_time}
    cfg = scenario_config(run.scenario, scenarios, **overrides)
    seeds = tuple(range(run.seed, run.seed + run.episodes))
    out.mkdir(parents=True, exist_ok=True)
    with owned_output(out, "scenario check"):
        bar = progress(total=2 * run.episodes, desc=f"check {scn.name}", unit="episode")
        acc = check_scenario(run.scenario, seeds, cfg, on_episode=lambda: bar.update(1), road=scn)
        bar.close()
        md = check_markdown(acc, scn.name)
        record = {
            "scenario": scn.name,
            "path": str(scn.path),
            "seeds": list(seeds),
            "max_time": cfg.max_time,
            "expert": acc.expert,
            "sumo": acc.sumo,
            "speed_ratio": round(acc.speed_ratio, 4),
            "failures": acc.failures,
            "meets_bar": not acc.failures,
        }
        write_json(out / "check.json", record)
        atomic_write_text(out / "check.md", md)
    print(md)
    print(f"check: {out / 'check.md'}, {out / 'check.json'}")
    return acc


# ------------------------------------------------------------------------------------------ generate


@dataclass(frozen=True)
class GenerateRun:
    """Generated networks: what ``irlsim scenario generate`` parses its arguments into."""

    count: int
    """networks to generate (the kinds take turns: grid, spider, random)"""
    out: Path
    """output folder: NNNN_<kind>.net.xml and generate.json (every network's parameters)"""
    seed: int = 0
    """network i is drawn from (seed, i)"""


def generate_networks(run: GenerateRun) -> list[Path]:
    """Generate ``run.count`` networks into ``run.out`` (:mod:`irlsim.road.generate`); a network already
    there is kept (a rerun resumes). Writes ``generate.json``; prints where it wrote."""
    if run.count < 1:
        raise IrlsimError(f"--count must be >= 1, got {run.count}")
    if not 0 <= run.seed <= MAX_SEED:
        raise IrlsimError(f"--seed must be in 0..{MAX_SEED}, got {run.seed}")
    check_output_dir(run.out, "--out")
    manifest = run.out / "generate.json"
    if manifest.is_file() and json.loads(manifest.read_text()).get("seed") != run.seed:
        raise IrlsimError(f"--out {run.out} holds networks of another --seed: use that seed or another --out")
    run.out.mkdir(parents=True, exist_ok=True)
    paths = []
    with owned_output(run.out, "scenario generate"):
        params = [network_params(run.seed, i) for i in range(run.count)]
        for p in progress(params, desc="generate networks", unit="network"):
            paths.append(build_network(p, run.out))  # one already there is kept: resumed
        entries = [{**asdict(p), "file": p.file_name} for p in params]
        write_json(manifest, {"seed": run.seed, "count": run.count, "networks": entries})
    print(f"networks: {run.count} in {run.out} (parameters in {manifest})")
    return paths

"""DAgger round sizes chosen by measurement: how the reward of each schedule drives, against its cost.

A schedule is the learner-driven train episodes of each DAgger round ("6" one round of 6, "6,20" two
rounds of 6 and 20). For every run folder ``<out>/new-seed<s>/`` of ``studies/recipe.py`` (its stage-1
``runs`` and its own DAgger rounds) and every schedule of ``--schedules``, the study

- runs the schedule's DAgger rounds in ``<folder>/rounds-<schedule>/`` with the recipe's DAgger config
  (configs/dagger/paper_fast.toml) and only the episodes changed, each step the command ``irlsim dagger``
  runs; a round whose inputs are the recipe's own (the same episodes and driver) is the recipe's round,
  linked, not run again;
- drives the last round's PACNN+S and PTACNN+S ``--episodes`` episodes of ``--laps`` laps on the
  development seeds (2000, 2001, ...; never the evaluation seeds), beside the expert on the same seeds;
  ``--dev-seeds 2000 2020`` adds a second sample of as many episodes (2020, 2021, ...), and a row counts
  every sample's episodes;
- writes ``<out>/rounds.md`` and ``<out>/rounds.json``: learner episodes, DAgger wall time (the sum of
  the rounds' recorded times), the closed-loop summary and the bar of each (schedule, seed, model).

The rule, fixed before the runs: the recipe takes the schedule with the fewest learner episodes whose
PACNN+S and PTACNN+S both meet the bar and keep the recipe's 95 % of the checkpoints in lane
(``recipe.MISSION_BAR``) with every training seed. Run from the repository root, alone on
the machine for the times to mean something:

    nice -n 5 .venv/bin/python studies/rounds.py --out runs/recipe --seeds 0 1 --schedules 6 6,10 6,20
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path
from typing import Any

sys.path.insert(0, str(Path(__file__).parent))
import recipe  # noqa: E402  (studies/recipe.py: the bar, the timed irlsim commands)

from irlsim.config import load_config  # noqa: E402
from irlsim.drive.metrics import summarize  # noqa: E402
from irlsim.workflows.dagger import DaggerConfig, DaggerRun, round_commands, step_name  # noqa: E402

DEV_SEED = 2000
DAGGER_CONFIG = recipe.RECIPES["new"][1]


def parse_schedule(text: str) -> tuple[int, ...]:
    """'6,20' -> (6, 20): positive episode counts per round."""
    try:
        sizes = tuple(int(x) for x in text.split(","))
    except ValueError:
        raise SystemExit(f"--schedules: {text!r} is not a comma-separated list of episode counts") from None
    if not sizes or min(sizes) < 1:
        raise SystemExit(f"--schedules: {text!r} needs one or more rounds of at least 1 episode")
    return sizes


def shared_rounds(schedule: tuple[int, ...], own: tuple[int, ...]) -> int:
    """How many leading rounds ``schedule`` shares with the recipe's own schedule ``own`` (their inputs are
    the same: the same episodes, each driven by the same previous round)."""
    n = 0
    while n < min(len(schedule), len(own)) and schedule[n] == own[n]:
        n += 1
    return n


def schedule_run(
    folder: Path, data: Path, schedule: tuple[int, ...], own: tuple[int, ...], stage2_last: bool = False
) -> Path:
    """The schedule's DAgger folder under ``folder``: the rounds it shares with the recipe's own linked,
    each other round's steps run (or resumed) as ``irlsim dagger`` runs them, one timed command each
    (:func:`irlsim.workflows.dagger.round_commands`); returns it. ``stage2_last``: PTACNN+S in the last
    round only (``stage2_every_round = false``; the rounds' PACNN+S and the last PTACNN+S are the same)."""
    name = f"rounds-{'-'.join(map(str, schedule))}" + ("-s2last" if stage2_last else "")
    here = folder / name
    here.mkdir(exist_ok=True)
    shared = shared_rounds(schedule, own)
    for r in range(1, shared + 1):
        link = here / f"round_{r}"
        if not link.exists():
            link.symlink_to((folder / "dagger" / f"round_{r}").resolve(), target_is_directory=True)
    overrides: dict[str, Any] = {
        "rounds": len(schedule),
        "episodes": list(schedule),
        "epochs": [5] * len(schedule),
        "stage2_every_round": not stage2_last,
    }
    cfg = load_config(DaggerConfig, DAGGER_CONFIG, {**overrides, "seed": _seed(folder)})
    run = DaggerRun(cfg, data, folder / "runs", here)
    for r in range(shared + 1, len(schedule) + 1):
        for cmd in round_commands(run, r):  # after round r - 1: round r's plan names its checkpoint
            recipe.run(cmd, here / "times.json", f"round {r} {step_name(cmd)}")
    return here


def _seed(folder: Path) -> int:
    return int(folder.name.rsplit("seed", 1)[1])


def dagger_seconds(here: Path, stage2_last: bool = False) -> float:
    """The schedule's DAgger wall time: the recorded times of the rounds it shares with the recipe
    (their ``round.json``) and of the steps it ran itself (its ``times.json``). ``stage2_last``: a
    linked round before the last counts without its stage 2 (the schedule would not have run it)."""
    rounds = {int(d.name.split("_")[1]): d / "round.json" for d in here.glob("round_*")}
    linked = 0.0
    for r, record in rounds.items():
        if record.is_file():
            rec = json.loads(record.read_text())
            linked += float(rec.get("wall_s", 0.0))
            if stage2_last and r < max(rounds):
                linked -= float(rec.get("steps_s", {}).get("train stage 2", 0.0))
    times = here / "times.json"
    steps = json.loads(times.read_text()) if times.is_file() else {}
    return round(linked + sum(v for k, v in steps.items() if k.startswith("round ")), 1)


def dev_drive(out: Path, runs: Path | None, models: tuple[str, ...], a: Any) -> list[dict[str, Any]]:
    """``models`` on every development sample of ``a.dev_seeds`` (``a.episodes`` episodes from each seed)
    into ``out`` (one folder a sample, kept); their episodes, every sample's together."""
    eps = []
    for seed in a.dev_seeds:
        here = out.with_name(out.name + ("" if seed == DEV_SEED else f"-s{seed}"))
        times, step = out.parent / "times.json", f"development drive {here.name}"
        eps += recipe.drive(here, runs, models, a, times, seed=seed, step=step)
    return eps


def check_dev_seeds(starts: list[int], episodes: int) -> None:
    """Refuse development samples outside the development seeds (2000-2999; the evaluations use 1000-1999
    and 3000-) or overlapping one another (an episode counted twice)."""
    seeds = sorted(starts)
    if seeds[0] < DEV_SEED or seeds[-1] + episodes > DEV_SEED + 1000:
        raise SystemExit(
            f"--dev-seeds: every sample must lie in the development seeds {DEV_SEED}-{DEV_SEED + 999}"
        )
    if any(b < a + episodes for a, b in zip(seeds, seeds[1:], strict=False)):
        raise SystemExit(f"--dev-seeds: samples of {episodes} episodes overlap; start them {episodes} apart")


def choose(rows: list[dict[str, Any]]) -> str | None:
    """The rule: the schedule with the fewest learner episodes whose every row (both models, every seed)
    meets the bar; None when none does."""
    ok: dict[str, bool] = {}
    for r in rows:
        ok[r["schedule"]] = ok.get(r["schedule"], True) and bool(r["bar"])
    passing = [s for s, good in ok.items() if good]
    return min(passing, key=lambda s: (sum(parse_schedule(s)), len(parse_schedule(s)))) if passing else None


def table(rows: list[dict[str, Any]]) -> str:
    head = "schedule | seed | model | learner episodes | DAgger [min] | collisions | exits | stops"
    head += " | checkpoints in lane | speed / expert | bar, in lane >= 95 %"
    lines = [f"| {head} |", "|" + "---|" * (head.count("|") + 1)]
    for r in rows:
        s = r["drive"]
        label = r["schedule"] + (" (stage 2 last)" if r.get("stage2_last") else "")
        cells = [label, r["seed"], r["model"], r["episodes"], f"{r['dagger_s'] / 60:.1f}"]
        cells += [*recipe.closed_loop_cells(s), f"{r['speed_ratio']:.3f}", "yes" if r["bar"] else "no"]
        lines.append("| " + " | ".join(map(str, cells)) + " |")
    return "\n".join(lines) + "\n"


def main() -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--out", default="runs/recipe", help="the recipe study's folder (studies/recipe.py)")
    p.add_argument("--config", default="configs/collect/paper.toml", help="the collect config")
    p.add_argument("--seeds", type=int, nargs="+", default=[0, 1], help="training seeds")
    p.add_argument("--schedules", nargs="+", default=["6", "6,10", "6,20"])
    p.add_argument(
        "--episodes", type=int, default=20,
        help="development episodes per model (20 of 2 laps: 80 stops, as many as the evaluation's; the 99 %% "
        "stop bound allows no miss in fewer than 100)",
    )  # fmt: skip
    p.add_argument(
        "--dev-seeds", type=int, nargs="+", default=[DEV_SEED],
        help="first seed of each development sample of --episodes episodes (a row sums every sample)",
    )  # fmt: skip
    p.add_argument("--laps", type=int, default=2, help="laps per episode")
    p.add_argument(
        "--stage2-last", action="store_true",
        help="PTACNN+S in the last round only (the same models, without the earlier rounds' stage 2)",
    )  # fmt: skip
    p.add_argument("--workers", type=int, default=2, help="episodes driven in parallel")
    a = p.parse_args()
    a.out = Path(a.out)
    check_dev_seeds(a.dev_seeds, a.episodes)
    schedules = [parse_schedule(s) for s in a.schedules]
    folders = [a.out / f"new-seed{s}" for s in a.seeds]
    for f in folders:
        if not (f / "dagger").is_dir():
            raise SystemExit(f"{f} has no DAgger rounds: run studies/recipe.py --recipes new first")
    expert = summarize(dev_drive(a.out / f"expert-dev{a.episodes}", None, ("expert",), a))
    rows = []
    for f in folders:
        for sched in schedules:
            here = schedule_run(f, a.out / "data", sched, own_schedule(f), a.stage2_last)
            last = here / f"round_{len(sched)}" / "runs"
            eps = dev_drive(here / f"dev{a.episodes}", last, recipe.MODELS, a)
            for m in recipe.MODELS:
                s = summarize([e for e in eps if e["drive/model"] == m])
                kmh = expert["drive/mean_speed_kmh"]
                rows.append({
                    "schedule": ",".join(map(str, sched)), "stage2_last": a.stage2_last,
                    "seed": _seed(f), "model": m,
                    "episodes": sum(sched), "dagger_s": dagger_seconds(here, a.stage2_last), "drive": s,
                    "speed_ratio": s["drive/mean_speed_kmh"] / kmh,
                    "bar": recipe.meets_bar(s, kmh) and recipe.in_lane(s) >= recipe.MISSION_BAR,
                })  # fmt: skip
    chosen = choose(rows)
    text = table(rows) + f"\nchosen by the rule: {chosen or 'none meets the bar'}\n"
    (a.out / "rounds.json").write_text(json.dumps({"rows": rows, "chosen": chosen}, indent=1) + "\n")
    (a.out / "rounds.md").write_text(text)
    print(text + f"wrote {a.out / 'rounds.md'} and {a.out / 'rounds.json'}")
    return 0


def own_schedule(folder: Path) -> tuple[int, ...]:
    """The schedule the run in ``folder`` made its own DAgger rounds with (their records' episodes)."""
    records = sorted(folder.glob("dagger/round_*/round.json"), key=lambda p: int(p.parent.name.split("_")[1]))
    return tuple(int(json.loads(p.read_text())["inputs"]["episodes"]) for p in records)


if __name__ == "__main__":
    sys.exit(main())

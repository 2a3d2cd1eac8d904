"""Time to a driving reward: the paper-scale recipe as it was and as it is now, side by side.

A recipe is a stage-1 config and a DAgger config: train PACNN+S on the expert's data with the first,
then run the DAgger rounds of the second (each round collects learner-driven episodes the expert labels,
retrains PACNN+S and trains PTACNN+S on it). Both recipes share one dataset (collected first), and each
runs for every ``--seeds`` training seed, one after the other on the same cores; every step's wall time
is recorded (a DAgger round's own record, ``round.json``, gives its wall time; the DAgger time of a run is
the sum over the recipe's rounds). Then the PACNN+S and PTACNN+S of the recipe's last round (its DAgger
config's ``rounds``) of every run drive ``--episodes`` episodes of ``--laps`` laps on the evaluation seeds
(1000, 1001, ...) beside the expert, and Table I of each is taken on the dataset's test split:

- ``old``: ``configs/train/stage1.toml`` (20 epochs on every policy), ``configs/dagger/paper.toml``
  (two rounds of 6 and 20 learner episodes, each retrained from scratch, 20 and 10 epochs);
- ``new``: ``configs/train/stage1_sampled.toml`` (the same, each step on a sample of every cycle's
  policies), ``configs/dagger/paper_fast.toml`` (the same rounds, each fine-tuning the reward that drove
  it for 5 epochs).
- ``new3``: the new recipe with a third round of 10 learner episodes, PTACNN+S in the last round only
  (``configs/dagger/paper_fast3.toml``).
- ``new3p``: three rounds of 6, 10 and 10, PTACNN+S trained with the paper's plain NLL for 5 epochs
  (``configs/dagger/paper_fast3p.toml``).

Development variants of the new recipe, each one lever changed (``--recipes new-ft10 new-ftall``; they
share the new recipe's stage 1 of the same seed): ``new-ft10`` fine-tunes 10 epochs a round instead of 5,
``new-ftall`` fine-tunes on every policy of a cycle instead of a sample of 256, ``new-ft10-val`` fine-tunes
10 epochs and chooses the epoch on a validation split with 2 learner-driven episodes a round;
``new3-short`` is new3 with half the training: stage 1 for 10 epochs instead of 20 (its own stage 1)
and PTACNN+S for 5 instead of 10; ``new2p`` is new3p without its third round (rounds of 6 and 10). Choose
among them on development seeds (``--drive-seed 2000``: the drives, their folders and the table say the
seed), and judge the choice once on the evaluation seeds.

Every step is a command whose output is kept, so the study resumes where it stopped: a finished step is
recorded with its wall time and not run again (an interrupted one runs again, and its time is the run
that finished it). Run from the repository root, alone on the machine for the times to mean
something:

    nice -n 5 .venv/bin/python studies/recipe.py --out runs/recipe --recipes old new --seeds 0 1

The table goes to ``<out>/recipe.md`` and ``<out>/recipe.json``.
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import time
import tomllib
from pathlib import Path
from typing import Any

import numpy as np

from irlsim.drive.metrics import summarize

RECIPES = {
    "old": ("configs/train/stage1.toml", "configs/dagger/paper.toml"),
    "new": ("configs/train/stage1_sampled.toml", "configs/dagger/paper_fast.toml"),
    "new3": ("configs/train/stage1_sampled.toml", "configs/dagger/paper_fast3.toml"),
    "new3p": ("configs/train/stage1_sampled.toml", "configs/dagger/paper_fast3p.toml"),
    # development variants of the new recipe: its stage 1 (shared with the "new" run of the same seed) and
    # its DAgger config with the overrides of VARIANT_SETS, each one lever of the recipe changed
    "new-ft10": ("configs/train/stage1_sampled.toml", "configs/dagger/paper_fast.toml"),
    "new-ftall": ("configs/train/stage1_sampled.toml", "configs/dagger/paper_fast.toml"),
    "new-ft10-val": ("configs/train/stage1_sampled.toml", "configs/dagger/paper_fast.toml"),
    # a development variant of new3 with its own (shorter) stage 1: STAGE1_SETS and VARIANT_SETS
    "new3-short": ("configs/train/stage1_sampled.toml", "configs/dagger/paper_fast3.toml"),
    # a development variant of new3p without its third round: rounds of 6 and 10 (VARIANT_SETS)
    "new2p": ("configs/train/stage1_sampled.toml", "configs/dagger/paper_fast3p.toml"),
}
#: the stage-1 overrides of a variant with a stage 1 of its own: 10 epochs on the expert's data, not 20
STAGE1_SETS = {"new3-short": ["--set", "epochs=10"]}
#: the DAgger overrides of the variants: 10 fine-tuning epochs a round instead of 5; the rounds'
#: fine-tuning on every policy of a cycle instead of a sample of 256; 10 epochs with the model chosen on
#: a validation split that holds 2 learner-driven episodes a round beside the expert's (with the expert's
#: alone, the choice between epochs 5 and 10 took epoch 5 in both rounds: the same reward as 5 epochs)
VARIANT_SETS = {
    "new-ft10": ["--set", "epochs=[10, 10]"],
    "new-ftall": ["--set", 'stage1_config="configs/train/stage1.toml"'],
    "new-ft10-val": ["--set", "epochs=[10, 10]", "--set", "validation_episodes=2"],
    "new3-short": ["--set", "stage2_epochs=5"],
    "new2p": ["--set", "rounds=2", "--set", "episodes=[6, 10]", "--set", "epochs=[5, 5]"],
}
MODELS = ("PACNN+S", "PTACNN+S")
EVAL_SEED = 1000
MISSION_BAR = 0.95  # the recipe's own bar on checkpoints in lane (the closed-loop bar's is 90 %)


def run(cmd: list[str], times: Path, step: str) -> None:
    """Run ``irlsim`` ``cmd`` and record its wall time as ``step`` in ``times`` (a JSON object); a step
    recorded there finished before and is not run again (its time stays the one it took)."""
    spent = json.loads(times.read_text()) if times.is_file() else {}
    if step in spent:
        print(f"{step}: finished before ({spent[step]} s in {times})", flush=True)
        return
    print("$ irlsim", " ".join(cmd), flush=True)
    t0 = time.perf_counter()
    subprocess.run([str(Path(sys.executable).parent / "irlsim"), *cmd], check=True)
    spent[step] = round(time.perf_counter() - t0, 1)
    times.write_text(json.dumps(spent, indent=1) + "\n")


def recipe_run(
    out: Path, data: Path, recipe: str, seed: int, threads: int, dagger: bool = True
) -> dict[str, Any]:
    """Stage 1 and (``dagger``) the DAgger rounds of ``recipe`` with training seed ``seed``; their
    folder's record."""
    stage1, dagger_config = RECIPES[recipe]
    here = out / f"{recipe}-seed{seed}"
    here.mkdir(parents=True, exist_ok=True)
    times = here / "times.json"
    common = ["--set", f"seed={seed}", "--set", f"threads={threads}"]
    if recipe in VARIANT_SETS and recipe not in STAGE1_SETS:  # the new recipe's stage 1, run once for all
        base = recipe_run(out, data, "new", seed, threads, dagger=False)
        stage1_runs = Path(base["folder"]) / "runs"
        spent = json.loads(times.read_text()) if times.is_file() else {}
        times.write_text(json.dumps({**spent, "stage 1": base["times"]["stage 1"]}, indent=1) + "\n")
    else:
        stage1_runs = here / "runs"
        run(
            ["train", "--stage", "1", "--config", stage1, "--data", str(data), "--out", str(stage1_runs)]
            + ["--set", 'models=["PACNN+S"]', *common, *STAGE1_SETS.get(recipe, [])],
            times,
            "stage 1",
        )
    if dagger:
        run(
            ["dagger", "--config", dagger_config, "--data", str(data), "--runs", str(stage1_runs)]
            + ["--out", str(here / "dagger"), "--set", f"seed={seed}", *VARIANT_SETS.get(recipe, [])],
            times,
            "DAgger",
        )
    n = recipe_rounds(recipe)
    record = {"recipe": recipe, "seed": seed, "folder": here, "times": json.loads(times.read_text())}
    return {**record, "rounds": n, "dagger_s": dagger_seconds(here, n)}


def recipe_rounds(recipe: str) -> int:
    """The DAgger rounds of ``recipe``: its DAgger config's ``rounds``, or its variant's override."""
    sets = VARIANT_SETS.get(recipe, [])
    override = [s.removeprefix("rounds=") for s in sets if s.startswith("rounds=")]
    config = tomllib.loads(Path(RECIPES[recipe][1]).read_text())
    return int(override[-1]) if override else int(config["rounds"])


def last_round(folder: Path, n: int) -> Path:
    """The runs of round ``n`` of the run in ``folder``; exits with one line when it did not finish."""
    here = folder / "dagger" / f"round_{n}"
    if not (here / "round.json").is_file():
        raise SystemExit(f"{here} has not finished: run the study again to resume it")
    return here / "runs"


def dagger_seconds(folder: Path, n: int) -> float:
    """The wall time of rounds 1..n of the run in ``folder``: the sum of their records' (a folder may hold
    more rounds, run when the recipe had more)."""
    records = [folder / "dagger" / f"round_{r}" / "round.json" for r in range(1, n + 1)]
    return round(sum(float(json.loads(p.read_text())["wall_s"]) for p in records if p.is_file()), 1)


def drive(
    out: Path,
    runs: Path | None,
    models: tuple[str, ...],
    a: Any,
    times: Path,
    seed: int = EVAL_SEED,
    step: str = "acceptance drive",
) -> list[dict[str, Any]]:
    """``models`` driven ``a.episodes`` episodes from ``seed`` into ``out`` (kept: not driven again);
    their episodes."""
    if not (out / "drive.json").is_file():
        run(
            ["drive", *(["--runs", str(runs)] if runs else []), "--model", ",".join(models)]
            + ["--episodes", str(a.episodes), "--laps", str(a.laps), "--seed", str(seed)]
            + ["--config", a.config, "--frames", "0", "--workers", str(a.workers), "--out", str(out)],
            times,
            step,
        )
    return list(json.loads((out / "drive.json").read_text())["episodes"])


def accept(r: dict[str, Any], a: Any) -> dict[str, Any]:
    """Drive and Table I of the run's last-round models, beside the expert (driven once for every run, on
    the same seeds); their summaries and Table I rows."""
    n, here = r["rounds"], r["folder"]
    runs, table, times = last_round(here, n), here / f"table1-round{n}", here / "times.json"
    # on the evaluation seeds the folders and steps keep their names; on others (development) they say it
    at = "" if a.drive_seed == EVAL_SEED else f"-s{a.drive_seed}"
    step = "acceptance drive" + at
    eps = drive(
        a.out / f"expert{at}-e{a.episodes}", None, ("expert",), a, a.out / "times.json", a.drive_seed, step
    )
    eps += drive(
        here / f"accept-round{n}{at}-e{a.episodes}",
        runs,
        MODELS,
        a,
        times,
        a.drive_seed,
        f"{step}, round {n}",
    )
    if not (table / "results.json").is_file():  # on the data they were trained on: the expert's test split
        data = [str(a.out / "data"), *(str(here / "dagger" / f"round_{k}" / "data") for k in range(1, n + 1))]
        cmd = ["evaluate", "--data", *data, "--runs", str(runs), "--out", str(table)]
        run(cmd, times, f"Table I, round {n}")
    by_model = {m: summarize([e for e in eps if e["drive/model"] == m]) for m in ("expert", *MODELS)}
    rows = json.loads((table / "results.json").read_text())
    rows = rows.get("rows", rows) if isinstance(rows, dict) else rows
    opd = {x["model"]: x.get("OPD [m]", x.get("opd")) for x in rows if isinstance(x, dict) and "model" in x}
    return {"drive": by_model, "opd": opd}


def meets_bar(s: dict[str, Any], expert_kmh: float) -> bool:
    """The closed-loop bar: no collision or exit, >= 99 % of the stops, >= 90 % of the checkpoints in
    lane, >= 90 % of the expert's mean speed."""
    stops, passed = s["drive/stop_lines_compliant"], s["drive/stop_lines_passed"]
    lane, checkpoints = s["drive/checkpoints_in_lane"], s["drive/checkpoints_passed"]
    return (
        s["drive/collisions"] == 0
        and s["drive/exits"] == 0
        and (passed == 0 or stops >= 0.99 * passed)
        and checkpoints > 0
        and lane >= 0.9 * checkpoints
        and s["drive/mean_speed_kmh"] >= 0.9 * expert_kmh
    )


def in_lane(s: dict[str, Any]) -> float:
    """The share of the checkpoints passed in the mission's lane (0 when none was passed)."""
    passed = s["drive/checkpoints_passed"]
    return s["drive/checkpoints_in_lane"] / passed if passed else 0.0


def closed_loop_cells(s: dict[str, Any]) -> list[Any]:
    """A drive summary's collisions, exits, stops (compliant/passed), checkpoints (in lane/passed)."""
    stops = f"{s['drive/stop_lines_compliant']}/{s['drive/stop_lines_passed']}"
    return [
        s["drive/collisions"],
        s["drive/exits"],
        stops,
        f"{s['drive/checkpoints_in_lane']}/{s['drive/checkpoints_passed']}",
    ]


def table(rows: list[dict[str, Any]]) -> str:
    head = "recipe | seed | rounds | model | stage 1 [min] | DAgger [min] | to a reward [min]"
    head += " | collisions | exits | stops | checkpoints in lane | speed / expert | OPD [m] (test) | bar"
    head += f" | in lane >= {MISSION_BAR:.0%}"
    lines = [f"| {head} |", "|" + "---|" * (head.count("|") + 1)]
    for r in rows:
        t = r["times"]
        minutes = [t.get("stage 1", 0) / 60, r["dagger_s"] / 60]
        kmh = r["drive"]["expert"]["drive/mean_speed_kmh"]
        for m in MODELS:
            s = r["drive"][m]
            cells = [r["recipe"], r["seed"], r["rounds"], m, *(f"{x:.1f}" for x in (*minutes, sum(minutes)))]
            cells += [*closed_loop_cells(s), f"{s['drive/mean_speed_kmh'] / kmh:.3f}"]
            cells += [f"{r['opd'].get(m, float('nan')):.3f}"]
            cells += ["yes" if meets_bar(s, kmh) else "no", "yes" if in_lane(s) >= MISSION_BAR else "no"]
            lines.append("| " + " | ".join(map(str, cells)) + " |")
    return "\n".join(lines) + "\n"


def spread(rows: list[dict[str, Any]]) -> str:
    """Each recipe over its training seeds: time to a reward and every model's checkpoints in lane as mean
    and range, and the time's ratio to the old recipe's (mean over mean, the same run) when it ran."""
    by: dict[str, list[dict[str, Any]]] = {}
    for r in rows:
        by.setdefault(r["recipe"], []).append(r)
    minutes = {k: [(r["times"].get("stage 1", 0) + r["dagger_s"]) / 60 for r in rs] for k, rs in by.items()}
    lines = []
    for k, rs in by.items():
        t = minutes[k]
        text = f"- {k} ({len(rs)} training seeds): to a reward {_mean_range(t, '.1f')} min"
        if "old" in minutes and k != "old":
            text += f", {np.mean(minutes['old']) / np.mean(t):.2f}x faster than the old recipe"
        for m in MODELS:
            share = [100 * in_lane(r["drive"][m]) for r in rs]
            bar = sum(meets_bar(r["drive"][m], r["drive"]["expert"]["drive/mean_speed_kmh"]) for r in rs)
            text += f"; {m} in lane {_mean_range(share, '.1f')} %, the bar met with {bar} of {len(rs)}"
        lines.append(text)
    return "\n".join(lines) + "\n"


def _mean_range(xs: list[float], fmt: str) -> str:
    return f"{np.mean(xs):{fmt}} ({min(xs):{fmt}}-{max(xs):{fmt}})"


def main() -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--out", default="runs/recipe")
    p.add_argument("--config", default="configs/collect/paper.toml", help="the collect config")
    p.add_argument("--recipes", nargs="+", choices=sorted(RECIPES), default=["old", "new"])
    p.add_argument("--seeds", type=int, nargs="+", default=[0, 1], help="training seeds")
    p.add_argument("--episodes", type=int, default=20, help="acceptance episodes per model")
    p.add_argument("--laps", type=int, default=2, help="laps per acceptance episode")
    p.add_argument("--threads", type=int, default=2, help="torch threads of the stage-1 training")
    p.add_argument("--workers", type=int, default=2, help="acceptance episodes driven in parallel")
    p.add_argument(
        "--drive-seed", type=int, default=EVAL_SEED,
        help=f"first seed of the drives ({EVAL_SEED}: the evaluation seeds; choose on others, e.g. 2000)",
    )  # fmt: skip
    a = p.parse_args()
    a.out = Path(a.out)
    data = a.out / "data"
    a.out.mkdir(parents=True, exist_ok=True)
    manifest = data / "manifest.json"
    if not (manifest.is_file() and '"complete": true' in manifest.read_text()):
        run(["collect", "--config", a.config, "--out", str(data)], a.out / "times.json", "collect")
    runs = [recipe_run(a.out, data, k, s, a.threads) for k in a.recipes for s in a.seeds]
    rows = [{**r, **accept(r, a), "folder": str(r["folder"])} for r in runs]
    name = "recipe" if a.drive_seed == EVAL_SEED else f"recipe-s{a.drive_seed}"
    (a.out / f"{name}.json").write_text(json.dumps(rows, indent=1) + "\n")
    (a.out / f"{name}.md").write_text(table(rows) + "\n" + spread(rows))
    print(
        table(rows) + "\n" + spread(rows) + f"wrote {a.out / (name + '.md')} and {a.out / (name + '.json')}"
    )
    return 0


if __name__ == "__main__":
    sys.exit(main())

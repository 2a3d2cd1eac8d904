"""One reward, many roads: does a reward learned on some scenarios drive one it never saw?

For every held-out scenario X (every shipped scenario but the oval) three trainings are compared on X's
evaluation seeds (1000, 1001, ...), beside the expert and the expert's hand-tuned reward (expert-theta)
driven on the same seeds:

- zero-shot: trained on the oval alone (one training seed, ``--episodes-single`` episodes);
- leave-one-out: trained on every shipped scenario but X (``--seeds``, ``--episodes`` episodes);
- in-domain: trained on X alone (one training seed, ``--episodes-single`` episodes);
- DAgger on X (``--dagger X``): the leave-one-out reward of the first seed, taught on X by DAgger rounds
  (the learner drives X, the expert labels): X's own data, so an in-domain row of its own.

Each row also has Table I of its models on X's test split (``irlsim evaluate --held-out``).

Each scenario gets its own dataset (the collect config, its own base seed: 0, 1, 2, ... in the order
of ``shipped_scenarios()``), a training is ``irlsim train --data D1 D2 ...`` (the aggregate of the
datasets), and drives use ``irlsim drive --scenario X``. The expert and expert-theta are driven once per
road for the largest episode count; a row with fewer episodes is compared with their first episodes
(the same seeds). Every step is a separate command; a step whose output exists is skipped, so the study
resumes where it stopped. Run from the repository root:

    nice -n 5 .venv/bin/python studies/transfer.py --out runs/transfer --seeds 0 1 2 --episodes 20 \\
        --episodes-single 10 --dagger grid [--epochs 6] [--threads 2] [--workers 2]

The tables go to ``<out>/transfer.md`` (every training seed) and ``<out>/transfer_summary.md`` (mean and
spread over the leave-one-out seeds, and whether each row meets the closed-loop bar), with
``<out>/transfer.json``.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
from pathlib import Path
from typing import Any

from irlsim.drive.metrics import summarize
from irlsim.road.scenario import DEFAULT_SCENARIO, shipped_scenarios

#: the road the zero-shot rewards are trained on (the paper's course, the default road)
ZERO_SHOT = DEFAULT_SCENARIO

MODELS = ("LIRL", "PACNN+S", "PTACNN+S")
REFERENCES = ("expert", "expert-theta")
EVAL_SEED = 1000  # the drives' first seed: no dataset of this study uses seeds in 1000..1999


def run(cmd: list[str]) -> None:
    print("$", " ".join(cmd), flush=True)
    subprocess.run(cmd, check=True)


def irlsim() -> str:
    return str(Path(sys.executable).parent / "irlsim")


def training_sets(scenarios: list[str]) -> dict[str, list[str]]:
    """name -> the scenarios it trains on."""
    held = [s for s in scenarios if s != ZERO_SHOT]
    out = {f"{ZERO_SHOT}-only": [ZERO_SHOT]}
    for x in held:
        out[f"loo-{x}"] = [s for s in scenarios if s != x]
        out[f"in-{x}"] = [x]
    return out


def collect(out: Path, scenarios: list[str], config: str) -> None:
    for k, s in enumerate(scenarios):
        data = out / "data" / s
        if (data / "manifest.json").is_file() and '"complete": true' in (data / "manifest.json").read_text():
            continue
        run(
            [irlsim(), "collect", "--config", config, "--scenario", s, "--set", f"seed={k}"]
            + ["--workers", "1", "--out", str(data)]
        )


def train(out: Path, name: str, sets: list[str], seed: int, epochs: int, threads: int) -> Path:
    runs = out / "runs" / f"{name}-seed{seed}"
    data = ["--data", *(str(out / "data" / s) for s in sets)]
    common = ["--set", f"seed={seed}", "--set", f"threads={threads}"]
    # always called: a finished training is a no-op, a killed one resumes from its last epoch (a
    # checkpoint exists after the first epoch, so its presence does not say the training finished)
    run(
        [irlsim(), "train", "--stage", "1", "--config", "configs/train/stage1.toml", *data]
        + ["--out", str(runs), "--set", 'models=["LIRL","PACNN+S"]', "--set", f"epochs={epochs}", *common]
    )
    run(
        [irlsim(), "train", "--stage", "2", "--config", "configs/train/stage2.toml", *data]
        + ["--out", str(runs), "--set", 'models=["PTACNN+S"]', *common]
    )
    return runs


def drive(
    out: Path, x: str, name: str, models: tuple[str, ...], episodes: int, a: Any, runs: Path | None
) -> Path:
    """``irlsim drive`` of ``models`` on X for ``episodes`` episodes from EVAL_SEED; its drive.json."""
    target = out / "drive" / x / f"{name}-e{episodes}"
    if not (target / "drive.json").is_file():
        run(
            [irlsim(), "drive", *(["--runs", str(runs)] if runs else []), "--model", ",".join(models)]
            + ["--episodes", str(episodes), "--seed", str(EVAL_SEED), "--config", a.config]
            + ["--scenario", x, "--frames", "0", "--workers", str(a.workers), "--out", str(target)]
        )
    return target / "drive.json"


def table_one(out: Path, x: str, runs: Path, threads: int) -> dict[str, dict[str, Any]]:
    """Table I of ``runs``' models on X's test split: model -> its results.json row."""
    # a DAgger round's runs folder is <dagger>/round_<r>/runs: named by its DAgger folder and round
    name = runs.name if runs.name != "runs" else f"dagger-{runs.parent.parent.name}-{runs.parent.name}"
    target = out / "eval" / x / name
    if not (target / "results.json").is_file():
        # an in-domain reward was trained on X's own data: its test split, but not held-out data
        held_out = [] if name.startswith(f"in-{x}") else ["--held-out"]
        run(
            [irlsim(), "evaluate", "--data", str(out / "data" / x), "--runs", str(runs), *held_out]
            + ["--threads", str(threads), "--out", str(target)]
        )
    rows = json.loads((target / "results.json").read_text())
    rows = rows.get("rows", rows) if isinstance(rows, dict) else rows
    return {r["model"]: r for r in rows if isinstance(r, dict) and "model" in r}


def references(out: Path, x: str, episodes: int, drive_json: Path) -> dict[str, dict[str, Any]]:
    """The expert's and expert-theta's summaries over their first ``episodes`` episodes on X."""
    eps = json.loads(drive_json.read_text())["episodes"]
    out_: dict[str, dict[str, Any]] = {}
    for m in REFERENCES:
        mine = sorted((e for e in eps if e["drive/model"] == m), key=lambda e: e["drive/seed"])[:episodes]
        out_[m] = summarize(mine)
    return out_


def row(x: str, kind: str, seed: int, s: dict[str, Any], expert_kmh: float, t1: dict[str, Any]) -> dict:
    m = s["drive/model"]
    t = t1.get(m if m != "expert" else "executed", {})
    return {
        "scenario": x,
        "training": kind,
        "seed": seed,
        "model": m,
        "episodes": s["drive/episodes"],
        "collisions": s["drive/collisions"],
        "exits": s["drive/exits"],
        "red": s.get("drive/red_crossings", 0),
        "stops": [s["drive/stop_lines_compliant"], s["drive/stop_lines_passed"]],
        "mission": [s["drive/checkpoints_in_lane"], s["drive/checkpoints_passed"]],
        "speed_vs_expert": round(s["drive/mean_speed_kmh"] / max(expert_kmh, 1e-9), 3),
        "score": s.get("score/score"),
        "opd_m": t.get("OPD [m]", t.get("opd")),
        "evd": t.get("EVD", t.get("evd")),
    }


def rows_of(out: Path, x: str, kind: str, seed: int, runs: Path | None, drive_json: Path, a: Any, n: int):
    """The rows of one training on X: its models and the references over the same n episodes."""
    ref = references(out, x, n, drive(out, x, "reference", REFERENCES, a.max_episodes, a, None))
    t1 = table_one(out, x, runs, a.threads) if runs is not None else {}
    summaries = [
        s for s in json.loads(drive_json.read_text())["summary"] if s["drive/model"] not in REFERENCES
    ]
    kmh = ref["expert"]["drive/mean_speed_kmh"]
    return [row(x, kind, seed, s, kmh, t1) for s in [*summaries, *ref.values()]]


def dagger(out: Path, x: str, scenarios: list[str], a: Any) -> Path:
    """DAgger on X from the first seed's leave-one-out reward (resumes); its folder."""
    seed = a.seeds[0]
    sets = training_sets(scenarios)[f"loo-{x}"]
    folder = out / "dagger" / f"{x}-seed{seed}"
    run(
        [irlsim(), "dagger", "--config", a.dagger_config, "--data", *(str(out / "data" / s) for s in sets)]
        + ["--runs", str(out / "runs" / f"loo-{x}-seed{seed}"), "--scenario", x, "--out", str(folder)]
        + ["--set", f"seed={seed}", "--set", "workers=1", "--set", 'stage2_models=["PTACNN+S"]']
        + ["--set", f"epochs=[{a.epochs}, {a.epochs}]"]
    )
    return folder


def meets_bar(r: dict[str, Any]) -> bool:
    """The closed-loop bar: no collision, exit or red crossing, >= 99 % full stops, >= 90 % of the
    mission, >= 90 % of the expert's mean speed."""
    stops, mission = r["stops"], r["mission"]
    return (
        r["collisions"] == 0
        and r["exits"] == 0
        and r["red"] == 0
        and (stops[1] == 0 or stops[0] >= 0.99 * stops[1])
        and (mission[1] > 0 and mission[0] >= 0.9 * mission[1])
        and r["speed_vs_expert"] >= 0.9
    )


COLUMNS = "scenario | training | seed | model | episodes | collisions | exits | red | stops | mission"
COLUMNS += " | speed / expert | score | OPD [m] | EVD | bar"


def _fmt(v: Any) -> str:
    if isinstance(v, list):
        return f"{v[0]}/{v[1]}"
    if isinstance(v, float):
        return f"{v:.3f}"
    return "–" if v is None else str(v)


def markdown_rows(rows: list[dict[str, Any]]) -> str:
    lines = [f"| {COLUMNS} |", "|" + "---|" * (COLUMNS.count("|") + 1)]
    for r in sorted(rows, key=lambda r: (r["scenario"], r["training"], r["seed"], r["model"])):
        cells = [_fmt(v) for v in r.values()] + ["yes" if meets_bar(r) else "no"]
        lines.append("| " + " | ".join(cells) + " |")
    return "\n".join(lines) + "\n"


def _spread(xs: list[float], digits: int = 3) -> str:
    xs = [x for x in xs if x is not None]
    if not xs:
        return "–"
    mean = sum(xs) / len(xs)
    sd = (sum((x - mean) ** 2 for x in xs) / (len(xs) - 1)) ** 0.5 if len(xs) > 1 else 0.0
    return f"{mean:.{digits}f} ± {sd:.{digits}f}" if len(xs) > 1 else f"{mean:.{digits}f}"


def bar_summary(rows: list[dict[str, Any]]) -> str:
    """One line per road, training and model: totals over the training seeds, mean ± standard deviation
    of the speed ratio, the scorecard's score (0-100) and OPD over the seeds, and on how many seeds the
    bar is met."""
    groups: dict[tuple[str, str, str], list[dict[str, Any]]] = {}
    for r in rows:
        if r["model"] in REFERENCES and r["training"] != "leave-one-out":
            continue  # the references once per road (their leave-one-out rows are the same drives)
        key = (r["scenario"], r["training"] if r["model"] not in REFERENCES else "reference", r["model"])
        if r["model"] in REFERENCES and any(g["seed"] == r["seed"] for g in groups.get(key, [])):
            continue
        groups.setdefault(key, []).append(r)
    head = "scenario | training | model | seeds | episodes each | collisions | exits | red | stops | mission"
    head += " | speed / expert | score | OPD [m] | bar met"
    lines = [f"| {head} |", "|" + "---|" * (head.count("|") + 1)]
    for (x, kind, m), rs in sorted(groups.items()):
        if kind == "reference":
            rs = rs[:1]
        tot = {k: sum(r[k] for r in rs) for k in ("collisions", "exits", "red")}
        stops = [sum(r["stops"][i] for r in rs) for i in (0, 1)]
        mission = [sum(r["mission"][i] for r in rs) for i in (0, 1)]
        met = sum(meets_bar(r) for r in rs)
        cells = [x, kind, m, len(rs), rs[0]["episodes"], tot["collisions"], tot["exits"], tot["red"]]
        cells += [_fmt(stops), _fmt(mission), _spread([r["speed_vs_expert"] for r in rs])]
        cells += [_spread([r["score"] for r in rs], 1)]
        cells += [_spread([r["opd_m"] for r in rs]), f"{met}/{len(rs)}"]
        lines.append("| " + " | ".join(map(str, cells)) + " |")
    return "\n".join(lines) + "\n"


KINDS = {"loo": "leave-one-out", "in": "in-domain", ZERO_SHOT: "zero-shot"}


def study_rows(out: Path, plan: list[tuple[str, str, int, int]], sets: dict[str, list[str]], a: Any) -> list:
    """Train (if needed), drive and evaluate each (road, training, seed, episodes) of ``plan``."""
    rows: list[dict[str, Any]] = []
    for x, name, seed, n in plan:
        runs = out / "runs" / f"{name}-seed{seed}"
        if a.table_only and not (out / "drive" / x / f"{runs.name}-e{n}" / "drive.json").is_file():
            continue
        if not a.table_only:
            train(out, name, sets[name], seed, a.epochs, a.threads)
        drive_json = drive(out, x, runs.name, MODELS, n, a, runs)
        rows += rows_of(out, x, KINDS[name.split("-")[0]], seed, runs, drive_json, a, n)
    return rows


def dagger_rows(out: Path, scenarios: list[str], a: Any) -> list:
    """DAgger on each road of ``--dagger`` from the first seed's leave-one-out reward: every finished
    round's reward driven and evaluated as its own row (``DAgger on the road, round r``)."""
    rows: list[dict[str, Any]] = []
    for x in a.dagger:
        folder = out / "dagger" / f"{x}-seed{a.seeds[0]}"
        if not a.table_only:
            dagger(out, x, scenarios, a)
        finished = sorted(folder.glob("round_*/round.json"), key=lambda p: int(p.parent.name.split("_")[1]))
        for record in finished:
            r = int(record.parent.name.split("_")[1])
            name = f"dagger-{x}-seed{a.seeds[0]}-round{r}"
            if a.table_only and not (out / "drive" / x / f"{name}-e{a.episodes}" / "drive.json").is_file():
                continue
            runs = record.parent / "runs"
            drive_json = drive(out, x, name, ("PACNN+S", "PTACNN+S"), a.episodes, a, runs)
            rows += rows_of(
                out, x, f"DAgger on the road, round {r}", a.seeds[0], runs, drive_json, a, a.episodes
            )
    return rows


def main() -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--out", default="runs/transfer")
    p.add_argument("--config", default="configs/collect/default.toml")
    p.add_argument("--seeds", type=int, nargs="+", default=[0], help="training seeds of the leave-one-out")
    p.add_argument("--epochs", type=int, default=6, help="stage-1 epochs")
    p.add_argument("--episodes", type=int, default=20, help="evaluation episodes of the leave-one-out rows")
    p.add_argument("--episodes-single", type=int, default=10, help="episodes of the other rows")
    p.add_argument("--dagger", nargs="*", default=[], metavar="X", help="held-out roads taught by DAgger")
    p.add_argument("--dagger-config", default="configs/dagger/default.toml")
    p.add_argument("--threads", type=int, default=1, help="torch threads of each training")
    p.add_argument("--workers", type=int, default=1, help="episodes driven in parallel")
    p.add_argument("--table-only", action="store_true", help="only the table of the drives already done")
    a = p.parse_args()
    a.max_episodes = max(a.episodes, a.episodes_single)
    out = Path(a.out)
    os.environ.setdefault("OMP_NUM_THREADS", str(a.threads))
    scenarios = list(shipped_scenarios())
    held = [s for s in scenarios if s != ZERO_SHOT]
    sets = training_sets(scenarios)
    if not a.table_only:
        collect(out, scenarios, a.config)
    plan: list[tuple[str, str, int, int]] = []  # (road, training name, seed, episodes): most needed first
    plan += [(x, f"loo-{x}", seed, a.episodes) for seed in a.seeds for x in held]
    single = [(x, f"{ZERO_SHOT}-only", a.seeds[0], a.episodes_single) for x in held]
    single += [(x, f"in-{x}", a.seeds[0], a.episodes_single) for x in held]
    rows: list[dict[str, Any]] = []
    rows += study_rows(out, plan, sets, a)
    rows += dagger_rows(out, scenarios, a)
    rows += study_rows(out, single, sets, a)
    (out / "transfer.json").write_text(json.dumps(rows, indent=1) + "\n")
    (out / "transfer.md").write_text(markdown_rows(rows))
    (out / "transfer_summary.md").write_text(bar_summary(rows))
    print(f"wrote {out / 'transfer.md'}, {out / 'transfer_summary.md'} and {out / 'transfer.json'}")
    return 0


if __name__ == "__main__":
    sys.exit(main())

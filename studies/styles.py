# size-ok: the acceptance's whole chain (data, training, Table I, references, drives, table) in one file,
# each step a command the docs cite; the development variants are flags of it, not copies
"""Learn the reward of any driver: does a reward learned from a demonstrator drive in that demonstrator's
style, and more like it than like any other demonstrator?

Demonstrators (``--demonstrators``): the expert (configs/collect/default.toml), a cautious and an
assertive SUMO driver (configs/collect/styles/, their attributes and reasons written there before any
run) and, with ``recording``, SUMO run on its own (the wheel's ``sumo`` binary, SUMO's routing and
drivers, ``--fcd-output``) on the default road, imported as a recording (learned and driven with the
planner's top speed raised to ``REC_V_MAX``, the speeds SUMO's drivers reach there). For each demonstrator:

- a dataset on every road of ``--roads`` (its collect config; base seed = the road's index, so every
  demonstrator meets the same traffic);
- LIRL and PACNN+S trained on its datasets of all roads, one training per ``--seeds`` seed;
- Table I of those models on its own test split (``irlsim evaluate``);
- closed-loop drives of both models on every road, ``--episodes`` episodes on the evaluation seeds
  (episode seeds ``EVAL_BASE`` * 1e6 + i, which no dataset uses);
- its own driving on the same seeds, the style reference: the expert by ``irlsim drive --model expert``;
  a SUMO demonstrator by ``irlsim collect`` of its config with base seed ``EVAL_BASE`` (SUMO drives the
  ego with the demonstrator's type; a collection's train episode i has the seed ``EVAL_BASE`` * 1e6 + i,
  the drives' seed); the recording by its replay (a collection of the cars no training episode used).

The table (``<out>/styles.md`` and ``<out>/styles.json``): per road, one row per learned reward (model,
demonstrator it learned from, training seed), one column per demonstrator, each cell the style distance
(:func:`irlsim.rollout.style.style_distances`, each figure divided by its spread over the references'
episodes) and the row's
smallest cell marked; beside it the safety bounds of the row's drives. The recording's rows are driven
where it was recorded (the held-out cars' routes and starts; the others driven by SUMO from their
recorded states, ``irlsim drive --reactive``: replayed cars cannot see the ego, and rear-end it) and
compared with the recorded cars and the expert driven there.

Every step is a separate ``irlsim`` command whose output is kept; a step whose output exists is skipped,
so the study resumes where it stopped. Run from the repository root:

    nice -n 5 .venv/bin/python studies/styles.py --out runs/styles --seeds 0 1 2 --episodes 20 \\
        [--demonstrators expert cautious assertive recording] [--threads 2] [--workers 2]

``--smoke`` runs the whole chain at toy sizes (one training seed, one episode, a few cycles).

Development runs, to choose before the evaluation seeds judge: ``--eval-base 2000`` drives on the episode
seeds 2000 * 1e6 + i instead (its drives, references and table named ``-s2000``); ``--rule kept`` trains
the rewards of the demonstrators other than the expert with every demonstration kept as driven
(``safe_demos = false``: the training's rule that moves a demonstration labelled as a predicted
collision to the closest unlabelled policy fits the expert's planner, whose choice is never labelled
so, not a driver who followed closely and did not collide; their runs, drives and table named
``-kept``); ``--rows`` names the demonstrators whose learned rewards get rows (default: all; fewer: the
table's file named by them too), ``--models`` the learned rewards driven (default: both; both are always
trained). ``--safety`` drives the learned rewards within the planner's label filter (``irlsim drive
--safety``: no policy predicted to collide, leave the road or take an exit; their drives and table named
``-safe``), as a planner that uses a learned reward would; the references drive as before; ``--commit``:
the SUMO drivers' rewards finish their maneuvers (``irlsim drive --commit``, ``-commit``; not recordings);
``--full-stop``: the SUMO drivers' rewards stop at every stop line they can (``irlsim drive --full-stop``,
``-stop``; not recordings; :func:`drive_tag`). ``assertive-lc3`` is the assertive driver with lane
changes of 3 s instead of SUMO's jump (``demonstrator.lane_change_duration``); ``assertive-eidm`` that
driver with SUMO's Extended IDM, whose acceleration has a human driver's reaction time and jerk limit;
``sporty`` a fast, left-keeping EIDM driver at SUMO's default headway; ``sporty-split``,
``assertive-split`` and ``assertive-lc3-split`` those drivers with the split policy set (development
candidates).
"""

from __future__ import annotations

import argparse
import json
import math
import os
import re
import subprocess
import sys
from pathlib import Path
from typing import Any

import numpy as np

from irlsim.config import MAX_SEED
from irlsim.road import load_road
from irlsim.road.scenario import DEFAULT_SCENARIO
from irlsim.rollout.style import pool_styles, style_distances, style_spread

sys.path.insert(0, str(Path(__file__).parent))
from sumo_alone import sumo_alone  # noqa: E402  (studies/sumo_alone.py: SUMO drives the recording)

#: the demonstrators' collect configs: the expert's, then each SUMO driver of configs/collect/styles/ by its
#: file's name (``assertive_eidm.toml``: ``assertive-eidm``), each with its attributes' reasons
CONFIGS = {"expert": "configs/collect/default.toml"} | {
    p.stem.replace("_", "-"): f"configs/collect/styles/{p.name}"
    for p in sorted((Path(__file__).resolve().parents[1] / "configs" / "collect" / "styles").glob("*.toml"))
}
RECORDING = "recording"
MODELS = ("PACNN+S", "LIRL")
#: --rule: how the demonstrations of a demonstrator other than the expert are trained on ("default": the
#: training config's rules for every demonstrator)
RULES = {"default": [], "kept": ["--set", "safe_demos=false"]}
EVAL_BASE = 1000  # evaluation: episode seeds EVAL_BASE * 1e6 + i (no dataset of this study uses them)
SEED_STRIDE = 1_000_000  # irlsim.data.collection.SEED_STRIDE
REC_CARS = 60  # cars SUMO drives for the recording (training, validation and test egos, then the drives')
REC_SEED = 1  # SUMO's seed of the recording
#: sizes: policies, recorded cars, seconds after the last departure, training egos, cycles per episode
SIZES = {"n_policies": 500, "rec_cars": REC_CARS, "rec_seconds": 200, "rec_train": 20, "collect_cycles": 800}
#: [m/s] the planner's top speed where the recording is learned and driven: SUMO's default drivers drive
#: the oval at up to their speedFactor x its 100 km/h limit (36 % of the recorded rows above the default
#: 25 m/s, 5 % above 30), and a policy set that cannot reach a driver's speed cannot hold its odometry
REC_V_MAX = 35.0

#: toy sizes of --smoke: the collect configs' fields (written to <out>/smoke/, as drives read them too)
SMOKE_FIELDS = {"n_policies": 60, "n_vehicles": 3, "max_cycles": 40, "workers": 1}
SMOKE_FIELDS |= {"train_episodes": 1, "validation_episodes": 1, "test_episodes": 1}
SMOKE_TRAIN = ["--set", "epochs=1"]
SMOKE_CYCLES = 8


def smoke_configs(out: Path) -> dict[str, str]:
    """The demonstrators' collect configs at toy sizes (``SMOKE_FIELDS``), written under ``out``."""
    (out / "smoke").mkdir(parents=True, exist_ok=True)
    configs = {}
    for d, src in CONFIGS.items():
        text = Path(src).read_text()
        for k, v in SMOKE_FIELDS.items():
            text = re.sub(rf"^{k} = [^#\n]*", f"{k} = {v} ", text, flags=re.M)
        (out / "smoke" / f"{d}.toml").write_text(text)
        configs[d] = str(out / "smoke" / f"{d}.toml")
    return configs


def run(cmd: list[str]) -> None:
    print("$", " ".join(cmd), flush=True)
    subprocess.run(cmd, check=True)


def irlsim() -> str:
    return str(Path(sys.executable).parent / "irlsim")


def complete(folder: Path) -> bool:
    m = folder / "manifest.json"
    return m.is_file() and '"complete": true' in m.read_text()


def collect(config: str, road: str, out: Path, sets: list[str], a: Any) -> None:
    if not complete(out):
        run(
            [irlsim(), "collect", "--config", config, "--scenario", road, *a.collect_sets, *sets]
            + ["--workers", str(a.workers), "--out", str(out)]
        )


def collected_episodes(folder: Path) -> list[dict[str, Any]]:
    """The style figures of every episode a collection recorded (those that drove)."""
    stats = [json.loads(p.read_text()) for p in sorted(folder.glob("*/*.stats.json"))]
    return [s for s in stats if s.get("style/time_s", 0) > 0]


def driven_episodes(drive_json: Path, model: str) -> list[dict[str, Any]]:
    """The style figures of every episode ``model`` drove in a drive.json (those that drove)."""
    eps = json.loads(drive_json.read_text())["episodes"]
    return [e for e in eps if e["drive/model"] == model and e.get("style/time_s", 0) > 0]


def driven_styles(drive_json: Path) -> dict[str, dict[str, Any]]:
    """model -> the pooled style of its episodes in a drive.json."""
    eps = json.loads(drive_json.read_text())["episodes"]
    return {
        m: pool_styles([e for e in eps if e["drive/model"] == m])
        for m in dict.fromkeys(e["drive/model"] for e in eps)
    }


def safety(drive_json: Path, model: str) -> dict[str, Any]:
    """The safety bounds of a model's drives (:func:`bounds`)."""
    return bounds(next(s for s in json.loads(drive_json.read_text())["summary"] if s["drive/model"] == model))


def collected_bounds(folder: Path) -> dict[str, Any]:
    """The safety bounds (:func:`bounds`) of a demonstrator's own driving in a collection: its
    episodes' counts added up."""
    stats = [json.loads(p.read_text()) for p in sorted(folder.glob("*/*.stats.json"))]
    keys = ["collisions", "exits", "red_crossings", "stop_lines_compliant", "stop_lines_passed"]
    keys += ["checkpoints_in_lane", "checkpoints_passed"]
    return bounds({f"drive/{k}": sum(int(s.get(f"sim/{k}", 0)) for s in stats) for k in keys})


def bounds(s: dict[str, Any]) -> dict[str, Any]:
    """The safety bounds of a drive summary: collisions, exits, red crossings, full stops at stop lines;
    ``safe`` when none was broken (a collision, an exit, a red crossing, fewer than 99 % of the stops).
    The mission (checkpoints in the lane irlsim's route asks for) is reported beside them and not a
    bound: SUMO's drivers do not know irlsim's mission lanes, so their learned rewards cannot either."""
    out = {
        "collisions": s["drive/collisions"],
        "exits": s["drive/exits"],
        "red": s.get("drive/red_crossings", 0),
        "stops": [s["drive/stop_lines_compliant"], s["drive/stop_lines_passed"]],
        "mission": [s["drive/checkpoints_in_lane"], s["drive/checkpoints_passed"]],
    }
    kept = out["stops"][1] == 0 or out["stops"][0] >= 0.99 * out["stops"][1]
    out["safe"] = out["collisions"] == 0 and out["exits"] == 0 and out["red"] == 0 and kept
    return out


def drive(config: str, road: str | None, models: list[str], runs: Path | None, out: Path, a: Any) -> Path:
    """``irlsim drive`` of ``models`` on the evaluation seeds; its drive.json. On the recording
    (``road`` None) reactive: SUMO drives the other cars, as a replayed car cannot see the ego."""
    if not set(models) <= driven_models(out / "drive.json"):  # a drive of fewer models is driven again
        where = ["--scenario", road] if road else ["--reactive"]
        rules = ["--commit"] * a.commit + ["--full-stop"] * a.full_stop if road else []  # not recordings
        where += ["--safety"] * a.safety + rules if runs else []
        run(
            [irlsim(), "drive", *(["--runs", str(runs)] if runs else []), "--model", ",".join(models)]
            + ["--episodes", str(a.episodes), "--seed", str(a.eval_base * SEED_STRIDE), "--config", config]
            + [*where, "--laps", str(a.laps), "--max-cycles", str(a.max_cycles), "--frames", "0"]
            + ["--workers", str(a.workers), "--out", str(out)]
        )
    return out / "drive.json"


def driven_models(drive_json: Path) -> set[str]:
    """The models a drive.json holds (none when there is none)."""
    if not drive_json.is_file():
        return set()
    return {s["drive/model"] for s in json.loads(drive_json.read_text())["summary"]}


def train(data: list[Path], runs: Path, seed: int, a: Any, rule: list[str]) -> None:
    # always called: a finished training is a no-op, a killed one resumes from its last epoch
    run(
        [irlsim(), "train", "--stage", "1", "--config", a.train_config, "--data", *map(str, data)]
        + ["--out", str(runs), "--set", f"models={json.dumps(list(MODELS))}", "--set", f"seed={seed}"]
        + ["--set", f"threads={a.threads}", "--set", f"epochs={a.epochs}", *a.train_sets, *rule]
    )


def add_rule_flags(p: argparse.ArgumentParser) -> None:
    """--commit and --full-stop, ``irlsim drive``'s rules for the learned rewards (every style study's)."""
    p.add_argument("--commit", action="store_true", help="learned rewards finish their maneuvers")
    p.add_argument("--full-stop", action="store_true", help="learned rewards stop at every line they can")


def drive_tag(
    safe: bool = False, commit: bool = False, stop: bool = False, choice: bool | str = False
) -> str:
    """The suffix of the studies' drive folders and tables: ``[-safe][-commit][-stop][-choice]`` (the
    expected choice; ``choice="maneuver"``: ``-maneuver``)."""
    last = "-maneuver" if choice == "maneuver" else "-choice" * bool(choice)
    return "-safe" * safe + "-commit" * commit + "-stop" * stop + last


def learner(d: str, a: Any) -> tuple[str, list[str]]:
    """The name of demonstrator ``d``'s learned rewards under ``--rule`` (``<d>[-<rule>]``: their rows'
    label, and with ``-seed<s>`` their folders), and the rule's training settings; the expert's always
    the default."""
    rule = "default" if d == "expert" else a.rule
    return d + ("" if rule == "default" else f"-{rule}"), RULES[rule]


def table_one(data: list[Path], runs: Path, out: Path, a: Any) -> dict[str, dict[str, Any]]:
    """Table I of ``runs``' models on the demonstrator's own test split: model -> OPD and EVD."""
    if not (out / "results.json").is_file():
        run(
            [irlsim(), "evaluate", "--data", *map(str, data), "--runs", str(runs)]
            + ["--threads", str(a.threads), "--out", str(out)]
        )
    rows = json.loads((out / "results.json").read_text())
    rows = rows.get("rows", rows) if isinstance(rows, dict) else rows
    return {
        r["model"]: {"opd_m": r.get("OPD [m]", r.get("opd")), "evd": r.get("EVD", r.get("evd"))}
        for r in rows
        if isinstance(r, dict) and r.get("model") in MODELS
    }


# ------------------------------------------------------------------------------------------ recording


def record(out: Path, a: Any, seed: int = REC_SEED) -> tuple[str, str]:
    """SUMO alone drives ``REC_CARS`` cars round the default road (its own routing: each car a trip of
    one lap, SUMO's default driver type, SUMO's ``seed``; another seed: folder ``recording-s<seed>``) with
    --fcd-output; the recording's collect and drive configs (training egos first, then the drives')."""
    folder = out / (RECORDING if seed == REC_SEED else f"{RECORDING}-s{seed}")
    fcd = folder / "traffic.fcd.xml"
    road = load_road(scenario=DEFAULT_SCENARIO)
    cars = a.rec_cars
    if not fcd.is_file():
        sumo_alone(fcd, road, cars, a.rec_seconds, seed)
    n_train = a.rec_train
    train_egos = ",".join(f"car{i}" for i in range(n_train + 2))
    drive_egos = ",".join(f"car{i}" for i in range(n_train + 2, n_train + 2 + a.episodes))
    common = (
        f'seed = 0\n\n[scenario]\nname = "{DEFAULT_SCENARIO}"\n\n[planner]\nn_policies = {a.n_policies}\n'
        f"v_max = {REC_V_MAX}\n"
    )
    rec = f'\n[demonstrator]\nkind = "recording"\nfile = "{fcd}"\nmin_duration = 20.0\n'
    splits = f"train_episodes = {n_train}\nvalidation_episodes = 1\ntest_episodes = 1\n"
    collect_toml, drive_toml = folder / "collect.toml", folder / "drive.toml"
    collect_toml.write_text(f'{splits}max_cycles = {a.collect_cycles}\n{common}{rec}ego = "{train_egos}"\n')
    drive_toml.write_text(f'{common}{rec}ego = "{drive_egos}"\n')
    ref = folder / "reference.toml"  # the drive egos' own recorded driving, as a collection
    ref.write_text(
        f"train_episodes = {a.episodes}\nvalidation_episodes = 0\ntest_episodes = 0\n"
        f'max_cycles = {a.max_cycles}\n{common}{rec}ego = "{drive_egos}"\n'
    )
    return str(collect_toml), str(drive_toml)


# ------------------------------------------------------------------------------------------ the table


def table_rows(
    learned: dict[str, dict[str, Any]], refs: dict[str, dict[str, Any]], spread: np.ndarray
) -> list[dict[str, Any]]:
    """One row per learned driving: the style distance to every reference (each figure divided by
    ``spread``, :func:`irlsim.rollout.style.style_spread` of the references' episodes), the nearest."""
    cols = list(refs)
    out = []
    for name, r in learned.items():
        d = style_distances([r["style"], *(refs[c] for c in cols)], spread)[0, 1:]
        cells = {c: float(x) for c, x in zip(cols, d, strict=True)}
        nearest = min(cells, key=lambda c: cells[c])
        own = nearest == r["demonstrator"]
        out.append({**{k: v for k, v in r.items() if k != "style"}, "row": name, "cells": cells})
        out[-1].update(nearest=nearest, own_nearest=own)
    return out


def markdown(tables: dict[str, dict[str, Any]]) -> str:
    parts = []
    for road, table in tables.items():
        rows = table["rows"]
        if not rows:
            continue
        cols = list(rows[0]["cells"])
        head = ["learned reward", *cols, "own nearest", *BOUNDS_HEAD]
        lines = [f"## {road}", "", "| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
        for r in rows:
            cells = [f"**{v:.3f}**" if c == r["nearest"] else f"{v:.3f}" for c, v in r["cells"].items()]
            own = "yes" if r["own_nearest"] else "no"
            lines.append("| " + " | ".join([r["row"], *cells, own, *bounds_cells(r["safety"])]) + " |")
        lines += ["", *verdicts(rows), "", "The demonstrators' own driving on the same seeds:", ""]
        lines += ["| demonstrator | " + " | ".join(BOUNDS_HEAD) + " |", "|" + "---|" * (len(BOUNDS_HEAD) + 1)]
        lines += [f"| {d} | " + " | ".join(bounds_cells(b)) + " |" for d, b in table["demonstrators"].items()]
        parts.append("\n".join(lines) + "\n")
    return "\n".join(parts)


BOUNDS_HEAD = ["collisions", "exits", "red", "stops", "mission", "safe"]


def bounds_cells(s: dict[str, Any]) -> list[str]:
    """The cells of :data:`BOUNDS_HEAD` for a :func:`bounds` record."""
    cells = [
        s["collisions"],
        s["exits"],
        s["red"],
        "{}/{}".format(*s["stops"]),
        "{}/{}".format(*s["mission"]),
    ]
    return [*map(str, cells), "yes" if s["safe"] else "no"]


def verdicts(rows: list[dict[str, Any]]) -> list[str]:
    """One line per model: in how many of its rows (demonstrator x training seed) the nearest driving is
    its own demonstrator's, and in how many every safety bound held."""
    out = []
    for m in dict.fromkeys(r["model"] for r in rows):
        mine = [r for r in rows if r["model"] == m]
        own = sum(r["own_nearest"] for r in mine)
        safe = sum(r["safety"]["safe"] for r in mine)
        out.append(
            f"- {m}: own demonstrator nearest in {own} of {len(mine)} rows; safe in {safe} of {len(mine)}"
        )
    return out


def study(a: Any) -> dict[str, dict[str, Any]]:
    out = Path(a.out)
    sumo_demos = [d for d in a.demonstrators if d in CONFIGS]
    data = {d: [out / "data" / d / r for r in a.roads] for d in sumo_demos}
    for d in sumo_demos:
        for k, road in enumerate(a.roads):
            collect(a.configs[d], road, data[d][k], ["--set", f"seed={k}"], a)
    rec = record(out, a) if RECORDING in a.demonstrators else None
    if rec is not None:
        data[RECORDING] = [out / "data" / RECORDING]
        collect(rec[0], DEFAULT_SCENARIO, data[RECORDING][0], [], a)
    tables: dict[str, dict[str, Any]] = {}
    at = "" if a.eval_base == EVAL_BASE else f"-s{a.eval_base}"  # development seeds: folders of their own
    safe = a.drive_tag  # the learned rewards' drives within the planner's filter, committed maneuvers
    for road in a.roads:  # the references: each demonstrator's own driving on the evaluation seeds
        episodes: dict[str, list[dict[str, Any]]] = {}
        own: dict[str, dict[str, Any]] = {}
        for d in sumo_demos:
            if d == "expert":
                ref = drive(a.configs[d], road, ["expert"], None, out / f"drive{at}" / road / "expert", a)
                episodes[d], own[d] = driven_episodes(ref, "expert"), safety(ref, "expert")
            else:
                folder = out / f"reference{at}" / d / road
                sets = ["--set", f"seed={a.eval_base}", "--set", f"train_episodes={a.episodes}"]
                sets += ["--set", "validation_episodes=0", "--set", "test_episodes=0"]
                sets += ["--set", f"max_cycles={a.max_cycles}", "--set", f"scenario.laps={a.laps}"]
                collect(a.configs[d], road, folder, sets, a)
                episodes[d], own[d] = collected_episodes(folder), collected_bounds(folder)
        refs = {d: pool_styles(e) for d, e in episodes.items()}
        learned: dict[str, dict[str, Any]] = {}
        for d in (d for d in sumo_demos if d in a.rows):
            tag, rule = learner(d, a)
            for seed in a.seeds:
                runs = out / "runs" / f"{tag}-seed{seed}"
                train(data[d], runs, seed, a, rule)
                t1 = table_one(data[d], runs, out / "eval" / runs.name, a)
                dj = drive(a.configs[d], road, a.models, runs, out / f"drive{at}{safe}" / road / runs.name, a)
                for m, style in driven_styles(dj).items():
                    row = {"model": m, "demonstrator": d, "seed": seed, "style": style, **t1.get(m, {})}
                    learned[f"{m} / {tag} / seed {seed}"] = {**row, "safety": safety(dj, m)}
        spread = style_spread([e for eps in episodes.values() for e in eps])
        tables[road] = {"rows": table_rows(learned, refs, spread), "demonstrators": own}
    if rec is not None and RECORDING in a.rows:
        tables[f"{DEFAULT_SCENARIO}, where the recording was made"] = recording_rows(out, rec, data, a)
    return tables


def recording_rows(out: Path, rec: tuple[str, str], data: dict[str, list[Path]], a: Any) -> dict[str, Any]:
    """The recording's learned rewards and the expert driven on the held-out cars' routes, against the
    recorded cars' own driving and the expert's there."""
    folder = out / "reference" / RECORDING
    collect(str(out / RECORDING / "reference.toml"), DEFAULT_SCENARIO, folder, [], a)
    expert = drive(rec[1], None, ["expert"], None, out / "drive" / RECORDING / "expert", a)
    episodes = {RECORDING: collected_episodes(folder), "expert": driven_episodes(expert, "expert")}
    refs = {d: pool_styles(e) for d, e in episodes.items()}
    own = {RECORDING: collected_bounds(folder), "expert": safety(expert, "expert")}
    learned: dict[str, dict[str, Any]] = {}
    tag, rule = learner(RECORDING, a)
    for seed in a.seeds:
        runs = out / "runs" / f"{tag}-seed{seed}"
        train(data[RECORDING], runs, seed, a, rule)
        t1 = table_one(data[RECORDING], runs, out / "eval" / runs.name, a)
        name = runs.name.removeprefix(f"{RECORDING}-")  # seed<s>, kept-seed<s>
        drives = out / f"drive{'-safe' * a.safety}" / RECORDING / name  # never --commit nor --full-stop
        dj = drive(rec[1], None, a.models, runs, drives, a)
        for m, style in driven_styles(dj).items():
            row = {"model": m, "demonstrator": RECORDING, "seed": seed, "style": style, **t1.get(m, {})}
            learned[f"{m} / {tag} / seed {seed}"] = {**row, "safety": safety(dj, m)}
    spread = style_spread([e for eps in episodes.values() for e in eps])
    return {"rows": table_rows(learned, refs, spread), "demonstrators": own}


def write_tables(out: Path, name: str, tables: dict[str, Any], show: bool = True) -> None:
    """``tables`` as ``<out>/<name>.json`` (NaN as null) and ``.md``; printed (``show``) and named."""
    (out / f"{name}.json").write_text(json.dumps(_finite(tables), indent=1, allow_nan=False) + "\n")
    (out / f"{name}.md").write_text(markdown(tables))
    print((markdown(tables) if show else "") + f"wrote {out / f'{name}.md'} and {out / f'{name}.json'}")


def _finite(x: Any) -> Any:
    """JSON without NaN: a NaN figure (no following) is null."""
    if isinstance(x, float) and not math.isfinite(x):
        return None
    if isinstance(x, dict):
        return {k: _finite(v) for k, v in x.items()}
    if isinstance(x, list):
        return [_finite(v) for v in x]
    return float(x) if isinstance(x, np.floating) else x


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--out", default="runs/styles")
    p.add_argument("--roads", nargs="+", default=[DEFAULT_SCENARIO, "motorway"])
    p.add_argument("--demonstrators", nargs="+", default=["expert", "cautious", "assertive"])
    p.add_argument("--seeds", type=int, nargs="+", default=[0, 1, 2], help="training seeds")
    p.add_argument("--episodes", type=int, default=20, help="evaluation episodes per road")
    p.add_argument("--epochs", type=int, default=6, help="stage-1 epochs")
    p.add_argument("--laps", type=int, default=2, help="laps of each evaluation episode")
    p.add_argument("--max-cycles", type=int, default=800, help="cycles of each evaluation episode")
    p.add_argument("--threads", type=int, default=1, help="torch threads of each training")
    p.add_argument("--workers", type=int, default=1, help="episodes collected or driven in parallel")
    p.add_argument("--smoke", action="store_true", help="toy sizes end to end (about a minute)")
    p.add_argument("--eval-base", type=int, default=EVAL_BASE, help="the drives' seeds: base * 1e6 + i")
    p.add_argument("--rule", choices=sorted(RULES), default="default", help="the non-experts' demonstrations")
    p.add_argument("--rows", nargs="+", help="demonstrators whose learned rewards get rows (default: all)")
    p.add_argument("--models", nargs="+", choices=MODELS, default=list(MODELS), help="the rewards driven")
    p.add_argument("--safety", action="store_true", help="learned rewards within the label filter (--safety)")
    add_rule_flags(p)
    a = p.parse_args(argv)
    a.drive_tag = drive_tag(a.safety, a.commit, a.full_stop)  # the drives' and the table's names
    a.rows = a.rows or a.demonstrators
    if RECORDING in a.rows and a.eval_base != EVAL_BASE:
        sys.exit(
            "styles: --eval-base moves the drives on the SUMO roads only (the recording is driven on its "
            "held-out cars): leave recording out of --rows"
        )
    unknown = [d for d in [*a.demonstrators, *a.rows] if d not in (*CONFIGS, RECORDING)]
    if unknown:
        sys.exit(f"styles: unknown demonstrator {unknown[0]}: choose from {', '.join([*CONFIGS, RECORDING])}")
    if not 0 <= a.eval_base * SEED_STRIDE <= MAX_SEED - a.episodes:  # irlsim's seeds are 31-bit
        sys.exit(f"styles: --eval-base {a.eval_base} gives seeds beyond {MAX_SEED}: choose 0..2146")
    a.train_config, a.collect_sets, a.train_sets = "configs/train/stage1.toml", [], []
    vars(a).update(SIZES)
    if a.smoke:
        a.seeds, a.episodes, a.max_cycles, a.laps = a.seeds[:1], 1, SMOKE_CYCLES, 1
        a.train_config, a.train_sets = "configs/train/tiny_stage1.toml", SMOKE_TRAIN
        vars(a).update(n_policies=60, rec_cars=6, rec_seconds=60, rec_train=1, epochs=1, collect_cycles=40)
    a.configs = smoke_configs(Path(a.out)) if a.smoke else dict(CONFIGS)
    os.environ.setdefault("OMP_NUM_THREADS", str(a.threads))
    try:
        tables = study(a)
    except subprocess.CalledProcessError as e:  # the command printed its own one line above
        sys.exit(f"styles: step failed (exit {e.returncode}): {' '.join(map(str, e.cmd))}")
    out = Path(a.out)
    name = "styles" + ("" if a.eval_base == EVAL_BASE else f"-s{a.eval_base}")
    name += ("" if a.rule == "default" else f"-{a.rule}") + a.drive_tag
    name += "" if a.rows == a.demonstrators else "-" + "-".join(a.rows)  # a part of the table: its own file
    write_tables(out, name, tables, show=False)
    return 0


if __name__ == "__main__":
    sys.exit(main())

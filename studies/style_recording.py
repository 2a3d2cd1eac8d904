r"""The style study's recording rows on other cars, with the planner's rules of the road.

Reads a ``studies/styles.py`` run with the recording (its dataset and its rewards ``runs/recording-seed<s>``,
learned from SUMO's own drivers recorded outside irlsim) and drives those rewards where nothing was
learned or judged yet, the other cars driven by SUMO from their recorded states (``--reactive``), beside
the expert on the same routes and the cars' own recorded driving, compared as the study's table does:

- ``--sumo-seed S``: a second recording, SUMO run on its own again with seed ``S`` (the same trips), and
  its held-out cars (the study's numbering: cars 22-41), every one of them new: fresh evaluation cars;
- ``--cars 42 59``: other cars of the study's own recording (no dataset or drive of the study uses cars
  42-59): development cars, to choose a rule on before the fresh cars judge it.

``--rules`` are ``irlsim drive``'s rules for the learned rewards (``commit``, ``full-stop``,
``keep-distance``, this one with the time headway ``--headway``, the expert's 0.8 s by default, and
``in-lane`` with it: the distance kept in the lane the reward chooses;
``--safety`` adds the planner's label filter; ``--choice expected`` drives the decision the reward's
distribution expects, its lane-change bias calibrated on the recording's training data, one model at a
time, ``studies/style_choice.py``'s choice; the expert and the references drive as always). Writes
``<out>/recording-<cars>[-<rules>][-safe][-choice].md`` and ``.json``:

    .venv/bin/python studies/style_recording.py --out runs/styles --seeds 0 1 2 --cars 42 59 \
        --rules full-stop keep-distance --workers 2
    .venv/bin/python studies/style_recording.py --out runs/styles --seeds 0 1 2 --sumo-seed 2 \
        --rules full-stop keep-distance --workers 2
"""

from __future__ import annotations

import argparse
import json
import re
import sys
from pathlib import Path
from typing import Any

sys.path.insert(0, str(Path(__file__).parent))
import styles  # noqa: E402  (studies/styles.py: the study's folders, configs and commands)

from irlsim.planner.expert import FOLLOW_HEADWAY  # noqa: E402
from irlsim.reward import load_reward  # noqa: E402
from irlsim.reward.choice import lane_change_bias  # noqa: E402
from irlsim.rollout.style import pool_styles  # noqa: E402

RULES = {
    "commit": "--commit",
    "full-stop": "--full-stop",
    "keep-distance": "--keep-distance",
    "in-lane": "--in-lane",
}
# the output's name tags: styles.py's, and in-lane's
TAGS = {"commit": "-commit", "full-stop": "-stop", "keep-distance": "-dist", "in-lane": "-lane"}


def with_egos(src: Path, dst: Path, egos: list[str]) -> str:
    """``src`` (a recording's drive or reference config) with ``egos`` as its egos (and episodes)."""
    text = re.sub(r'ego = "[^"]*"', f'ego = "{",".join(egos)}"', src.read_text())
    dst.write_text(re.sub(r"^train_episodes = \d+", f"train_episodes = {len(egos)}", text, flags=re.M))
    return str(dst)


def sample(out: Path, a: Any) -> tuple[str, str, str]:
    """(name, drive config, reference config) of the cars driven: a second SUMO run's held-out cars, or
    cars ``a.cars`` of the study's recording."""
    if a.sumo_seed is not None:
        styles.record(out, a, a.sumo_seed)  # the same trips, SUMO's seed ``sumo_seed``
        folder, name = out / f"{styles.RECORDING}-s{a.sumo_seed}", f"s{a.sumo_seed}"
        return name, str(folder / "drive.toml"), str(folder / "reference.toml")
    first, last = a.cars
    name, folder = f"c{first}-{last}", out / styles.RECORDING
    egos = [f"car{i}" for i in range(first, last + 1)]
    drive = with_egos(folder / "drive.toml", folder / f"drive-{name}.toml", egos)
    return name, drive, with_egos(folder / "reference.toml", folder / f"reference-{name}.toml", egos)


def drive_learned(config: str, runs: Path, out: Path, a: Any) -> Path:
    """``irlsim drive --reactive`` of ``a.models`` of ``runs`` with ``a.rules``; its drive.json."""
    if not set(a.models) <= styles.driven_models(out / "drive.json"):
        styles.run(
            [styles.irlsim(), "drive", "--runs", str(runs), "--model", ",".join(a.models), "--reactive"]
            + [w for r in a.rules for w in [RULES[r], *([str(a.headway)] * (r == "keep-distance"))]]
            + ["--safety"] * a.safety
            + (["--choice", "expected", "--lane-change-bias", repr(bias(runs, out, a))] if a.choice else [])
            + ["--episodes", str(a.episodes), "--seed", str(a.eval_base * styles.SEED_STRIDE)]
            + ["--config", config, "--laps", str(a.laps), "--max-cycles", str(a.max_cycles), "--frames", "0"]
            + ["--workers", str(a.workers), "--out", str(out)]
        )
    return out / "drive.json"


def bias(runs: Path, out: Path, a: Any) -> float:
    """The lane-change bias of ``a.models``' one model in ``runs``, calibrated on the recording's training
    data and written beside the drive (``bias.json``)."""
    value = lane_change_bias(load_reward(a.models[0], runs=str(runs)), [a.data])
    out.mkdir(parents=True, exist_ok=True)
    (out / "bias.json").write_text(json.dumps({a.models[0]: value}) + "\n")
    print(f"{runs.name}: {a.models[0]}'s lane-change bias {value:.3f}", flush=True)
    return value


def table(out: Path, a: Any) -> tuple[str, dict[str, Any]]:
    name, drive_toml, ref_toml = sample(out, a)
    ref_folder = out / "reference" / f"{styles.RECORDING}-{name}"
    styles.collect(ref_toml, styles.DEFAULT_SCENARIO, ref_folder, [], a)
    where = f"{styles.RECORDING}-{name}"
    expert = styles.drive(drive_toml, None, ["expert"], None, out / "drive" / where / "expert", a)
    refs = {
        styles.RECORDING: pool_styles(styles.collected_episodes(ref_folder)),
        "expert": styles.driven_styles(expert)["expert"],
    }
    own = {styles.RECORDING: styles.collected_bounds(ref_folder), "expert": styles.safety(expert, "expert")}
    tag = "".join(TAGS[r] for r in a.rules) + (f"{a.headway:g}" if a.headway != FOLLOW_HEADWAY else "")
    tag += "-safe" * a.safety + "-choice" * a.choice
    learned: dict[str, dict[str, Any]] = {}
    for seed in a.seeds:
        runs = out / "runs" / f"{styles.RECORDING}-seed{seed}"
        t1 = styles.table_one([out / "data" / styles.RECORDING], runs, out / "eval" / runs.name, a)
        dj = drive_learned(drive_toml, runs, out / f"drive{tag}" / where / f"seed{seed}", a)
        for m, style in styles.driven_styles(dj).items():
            row = {
                "model": m,
                "demonstrator": styles.RECORDING,
                "seed": seed,
                "style": style,
                **t1.get(m, {}),
            }
            learned[f"{m} / {styles.RECORDING} / seed {seed}"] = {**row, "safety": styles.safety(dj, m)}
    what = f"SUMO seed {a.sumo_seed}'s held-out cars" if a.sumo_seed is not None else f"cars {name[1:]}"
    rules = [f"{r} {a.headway:g} s" if r == "keep-distance" else r for r in a.rules] + ["safety"] * a.safety
    rules += ["the expected choice"] * a.choice
    title = f"{styles.DEFAULT_SCENARIO}, the recording's {what}" + (f", {' '.join(rules)}" if rules else "")
    rows = styles.table_rows(learned, refs)
    return f"{styles.RECORDING}-{name}{tag}", {title: {"rows": rows, "demonstrators": own}}


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--out", default="runs/styles", help="a studies/styles.py run with the recording")
    p.add_argument("--seeds", type=int, nargs="+", default=[0, 1, 2], help="training seeds")
    which = p.add_mutually_exclusive_group(required=True)
    which.add_argument("--sumo-seed", type=int, help="a second SUMO run with this seed: its held-out cars")
    which.add_argument("--cars", type=int, nargs=2, metavar=("FIRST", "LAST"), help="cars of the recording")
    p.add_argument("--rules", nargs="*", choices=sorted(RULES), default=[], help="the learned rewards' rules")
    p.add_argument("--headway", type=float, default=FOLLOW_HEADWAY, help="keep-distance's headway [s]")
    p.add_argument("--safety", action="store_true", help="the learned rewards within the label filter")
    p.add_argument("--models", nargs="+", choices=styles.MODELS, default=list(styles.MODELS))
    p.add_argument("--choice", choices=["argmax", "expected"], default="argmax", help="the rewards' choice")
    p.add_argument("--laps", type=int, default=2)
    p.add_argument("--max-cycles", type=int, default=800)
    p.add_argument("--threads", type=int, default=2, help="torch threads of Table I")
    p.add_argument("--workers", type=int, default=1, help="cars driven in parallel")
    a = p.parse_args(argv)
    out = Path(a.out)
    if not a.headway > 0:
        sys.exit(f"style_recording: --headway must be a time headway > 0 s, got {a.headway}")
    if "in-lane" in a.rules and "keep-distance" not in a.rules:
        sys.exit("style_recording: in-lane keeps the following distance in a lane: add keep-distance")
    if a.choice == "expected" and len(a.models) != 1:
        sys.exit("style_recording: --choice expected calibrates one model's bias: give one of --models")
    a.choice = a.choice == "expected"
    if a.sumo_seed == styles.REC_SEED:
        sys.exit(f"style_recording: SUMO seed {a.sumo_seed} is the study's own recording: choose another")
    first = styles.SIZES["rec_train"] + 2  # cars before it: the training, validation and test egos
    if a.cars is not None and not styles.REC_CARS > a.cars[1] >= a.cars[0] >= first:
        sys.exit(
            f"style_recording: --cars must lie within {first}..{styles.REC_CARS - 1} (the others are learned)"
        )
    trained = [out / "runs" / f"{styles.RECORDING}-seed{s}" / "stage1" for s in a.seeds]
    if not styles.complete(out / "data" / styles.RECORDING) or not all(t.is_dir() for t in trained):
        sys.exit(f"style_recording: {out} holds no trained recording: run studies/styles.py with recording")
    # what styles.py's steps read: its sizes and the drives' seeds (the study's evaluation base)
    a.rule, a.commit, a.full_stop, a.collect_sets = "default", False, False, []
    a.eval_base, a.data = styles.EVAL_BASE, out / "data" / styles.RECORDING
    vars(a).update(styles.SIZES)  # styles.py's sizes
    a.episodes = 20 if a.cars is None else a.cars[1] - a.cars[0] + 1
    name, tables = table(out, a)
    styles.write_tables(out, name, tables)
    return 0


if __name__ == "__main__":
    sys.exit(main())

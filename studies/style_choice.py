r"""The style study's learned rewards driven with the ``expected`` choice instead of the argmax.

A learned reward is a maximum-entropy distribution over the policy set; the planner drives its single
most likely policy, which changes lanes far less often than the distribution expects
(``studies/style_openloop.py``). ``irlsim drive --choice expected`` drives the decision the distribution
expects instead (:mod:`irlsim.planner.choice`), with a lane-change bias calibrated on the reward's own
training data (:func:`irlsim.reward.choice.lane_change_bias`: as many lane changes on those states as the
distribution expects there).

Reads a ``studies/styles.py`` run made with the same options (its datasets, rewards and references;
nothing is trained again), calibrates each row's bias, drives the rows on the same episodes into
``<out>/drive[-s<base>]-choice/`` and lays out the table (``studies/style_norms.py --choice``: the distance
as defined and per episode, with the safety bounds):

    .venv/bin/python studies/style_choice.py --out runs/styles --eval-base 2000 --episodes 30 \
        --demonstrators expert cautious assertive --rows cautious assertive --workers 2

The biases go to ``<out>/choice-biases[-s<base>][-<rule>][-<model>].json`` (the model named unless
PACNN+S); a row's drive folder holding another model's drives is refused before any work (give that
model a study folder of its own). ``--commit`` and ``--full-stop`` add the planner's rules
(``<out>/drive[-s<base>][-commit][-stop]-choice/``); ``--dagger-rounds N`` drives the rewards of
``studies/style_dagger.py --rounds N`` instead (calibrated on their own training data: the driver's
dataset and the rounds'):

    .venv/bin/python studies/style_choice.py --out runs/styles --eval-base 2000 --episodes 30 \
        --demonstrators expert cautious assertive-eidm --rows assertive-eidm --dagger-rounds 1 \
        --commit --full-stop --workers 2
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path
from typing import Any

sys.path.insert(0, str(Path(__file__).parent))
import style_dagger  # noqa: E402
import style_norms  # noqa: E402
import styles  # noqa: E402  (studies/styles.py: the study's folders, configs and commands)

from irlsim.reward import load_reward  # noqa: E402
from irlsim.reward.choice import lane_change_bias  # noqa: E402


def row_bias(runs: Path, data: list[Path], model: str) -> float:
    """The lane-change bias of ``model`` in ``runs``, calibrated on the train splits of ``data``."""
    return lane_change_bias(load_reward(model, runs=str(runs)), list(data))


def other_model(folder: Path, model: str) -> str | None:
    """Why ``folder`` (a row's drive folder) cannot hold ``model``'s drives: another model's are there."""
    if not (folder / "drive.json").is_file():
        return None
    driven = {e["drive/model"] for e in json.loads((folder / "drive.json").read_text())["episodes"]}
    if model in driven:
        return None
    held = ", ".join(sorted(driven))
    return f"{folder} holds {held}'s drives, not {model}'s: give --out a study folder of its own"


def drive(d: str, road: str, runs: Path, bias: float, out: Path, a: Any) -> None:
    """``irlsim drive --choice expected`` of the row's model on the study's episodes (once)."""
    if (out / "drive.json").is_file():
        return
    styles.run(
        [styles.irlsim(), "drive", "--runs", str(runs), "--model", a.model]
        + ["--episodes", str(a.episodes), "--seed", str(a.eval_base * styles.SEED_STRIDE)]
        + ["--config", styles.CONFIGS[d], "--scenario", road, "--laps", str(a.laps)]
        + ["--max-cycles", str(a.max_cycles), "--frames", "0", "--workers", str(a.workers)]
        + ["--choice", a.choice, "--lane-change-bias", repr(bias), "--out", str(out)]
        + ["--commit"] * a.commit
        + ["--full-stop"] * a.full_stop
    )


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--out", default="runs/styles", help="a studies/styles.py run's folder")
    p.add_argument("--roads", nargs="+", default=[styles.DEFAULT_SCENARIO, "motorway"])
    p.add_argument("--demonstrators", nargs="+", default=["expert", "cautious", "assertive"])
    p.add_argument("--rows", nargs="+", default=["cautious", "assertive"], help="rows (the expert too)")
    p.add_argument("--seeds", type=int, nargs="+", default=[0, 1, 2], help="training seeds")
    p.add_argument("--episodes", type=int, default=20, help="evaluation episodes per road")
    p.add_argument("--eval-base", type=int, default=styles.EVAL_BASE, help="the drives' episode seed base")
    p.add_argument("--laps", type=int, default=2)
    p.add_argument("--max-cycles", type=int, default=800)
    p.add_argument("--workers", type=int, default=1, help="episodes driven in parallel")
    p.add_argument("--model", choices=styles.MODELS, default="PACNN+S", help="the learned reward driven")
    p.add_argument("--rule", choices=sorted(styles.RULES), default="default", help="the rows' training rule")
    p.add_argument("--dagger-rounds", type=int, choices=range(6), default=0, help="style_dagger.py's rewards")
    p.add_argument(
        "--choice", choices=["expected", "maneuver"], default="expected", help="irlsim drive --choice"
    )
    styles.add_rule_flags(p)
    a = p.parse_args(argv)
    bad = [d for d in [*a.demonstrators, *a.rows] if d not in styles.CONFIGS]
    if bad:
        sys.exit(f"style_choice: unknown demonstrator {bad[0]}: choose from {', '.join(styles.CONFIGS)}")
    if a.dagger_rounds and a.rule != "default":
        sys.exit("style_choice: --dagger-rounds drives style_dagger.py's rewards: leave --rule at default")
    if a.dagger_rounds:
        a.rule = style_dagger.rule(a.dagger_rounds)
        styles.RULES[a.rule] = []  # style_dagger.py's rows: the rounds' data is what differs
    out = Path(a.out)
    at = "" if a.eval_base == styles.EVAL_BASE else f"-s{a.eval_base}"
    tag = styles.drive_tag(commit=a.commit, stop=a.full_stop, choice=a.choice)
    folders = [
        out / f"drive{at}{tag}" / road / f"{styles.learner(d, a)[0]}-seed{seed}"
        for d in a.rows
        for seed in a.seeds
        for road in a.roads
    ]
    taken = [why for f in folders if (why := other_model(f, a.model))]
    if taken:
        sys.exit(f"style_choice: {taken[0]}")
    biases: dict[str, float] = {}
    for d in a.rows:
        for seed in a.seeds:
            rounds = range(1, a.dagger_rounds + 1)
            data = [out / "data" / d / road for road in a.roads]
            data += [style_dagger.round_folder(out, d, seed, r, road) for r in rounds for road in a.roads]
            runs = out / "runs" / f"{styles.learner(d, a)[0]}-seed{seed}"
            missing = [str(x) for x in [*data, runs] if not x.is_dir()]
            if missing:
                script = "style_dagger.py" if a.dagger_rounds else "styles.py"
                sys.exit(f"style_choice: {missing[0]} is missing: run studies/{script} with the same options")
            biases[runs.name] = row_bias(runs, data, a.model)
            print(f"{runs.name}: {a.model}'s lane-change bias {biases[runs.name]:.3f}", flush=True)
            for road in a.roads:
                drive(d, road, runs, biases[runs.name], out / f"drive{at}{tag}" / road / runs.name, a)
    rule = "" if a.rule == "default" else f"-{a.rule}"
    model = "" if a.model == "PACNN+S" else f"-{a.model}"
    (out / f"choice-biases{at}{rule}{model}.json").write_text(json.dumps(biases, indent=1) + "\n")
    norms = ["--out", str(out), "--roads", *a.roads, "--demonstrators", *a.demonstrators]
    norms += [
        "--rows",
        *a.rows,
        "--seeds",
        *map(str, a.seeds),
        "--eval-base",
        str(a.eval_base),
        "--choice",
        a.choice,
    ]
    norms += ["--rule", a.rule] + ["--commit"] * a.commit + ["--full-stop"] * a.full_stop
    return style_norms.main(norms)


if __name__ == "__main__":
    sys.exit(main())

r"""The style study's SUMO drivers' rewards after a DAgger round in which SUMO's driver labels.

A reward learned from a SUMO driver drives into states its driver seldom visited (the assertive driver's
rewards keep 3 s and more behind the leader, where the driver closes up and pulls out), and there it
has no demonstration to learn from. One DAgger round gives it some: each training seed's PACNN+S reward
drives ``--round-episodes`` episodes on each road (``irlsim collect --driver``, DAgger round 1's seeds,
disjoint from every dataset's), and every cycle SUMO's driver labels the reward's own state (from a
saved simulation state it drives the horizon, and its odometry projected onto the cycle's policy set is
the demonstration: :mod:`irlsim.sim.branch`). PACNN+S and LIRL are trained again with the same seed on
the driver's dataset and the round's together (``--rounds N``: round r's reward drives round r + 1, and
the last is trained on every round), and PACNN+S is driven on the study's episodes with the
study's rules; the table is ``studies/style_norms.py``'s (as defined, and pooled as before 2026-12-01).

Reads a ``studies/styles.py`` run made with the same options (its datasets, rewards and references);
writes the rounds' data to ``<out>/dagger/<row>-seed<s>/[round<r>/]<road>``, the rewards to
``<out>/runs/<row>-sumo-dagger[<r>]-seed<s>``, their drives beside the study's and the table to
``<out>/style-norms[-s<base>]-sumo-dagger[<r>][-commit][-stop]-<rows>.md``:

    .venv/bin/python studies/style_dagger.py --out runs/styles --eval-base 2000 --episodes 30 \
        --rows assertive --workers 2 --threads 2 --commit --full-stop
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
from pathlib import Path
from typing import Any

sys.path.insert(0, str(Path(__file__).parent))
import style_norms  # noqa: E402
import styles  # noqa: E402  (studies/styles.py: the study's folders, configs and commands)

#: the rows' name: ``<row>-sumo-dagger`` (styles.learner), trained by this script alone
RULE = "sumo-dagger"
MODEL = "PACNN+S"


def rule(r: int) -> str:
    """The rows' name after round ``r``: ``sumo-dagger``, ``sumo-dagger2``, ..."""
    return RULE + (str(r) if r > 1 else "")


def round_folder(out: Path, d: str, seed: int, r: int, road: str) -> Path:
    """Where round ``r`` of row ``d``'s training seed ``seed`` collected on ``road``."""
    return out / "dagger" / f"{d}-seed{seed}" / ("" if r == 1 else f"round{r}") / road


def dagger_round(d: str, seed: int, out: Path, a: Any, r: int = 1) -> list[Path]:
    """Round ``r`` of row ``d``'s seed: the reward of round r - 1 drives (round 1: the study's), SUMO's
    driver labels; the folders, per road."""
    folders = []
    driver = out / "runs" / (f"{d}-seed{seed}" if r == 1 else f"{d}-{rule(r - 1)}-seed{seed}")
    for k, road in enumerate(a.roads):
        folder = round_folder(out, d, seed, r, road)
        if not styles.complete(folder):
            styles.run(
                [styles.irlsim(), "collect", "--config", styles.CONFIGS[d], "--scenario", road]
                + ["--driver", MODEL, "--runs", str(driver), "--round", str(r)]
                + ["--set", f"seed={k}", "--set", f"train_episodes={a.round_episodes}"]
                + ["--set", "validation_episodes=0", "--set", "test_episodes=0"]
                + ["--workers", str(a.workers), "--out", str(folder)]
            )
        folders.append(folder)
    return folders


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--out", default="runs/styles", help="a studies/styles.py run's folder")
    p.add_argument("--roads", nargs="+", default=[styles.DEFAULT_SCENARIO, "motorway"])
    p.add_argument("--demonstrators", nargs="+", default=["expert", "cautious", "assertive"])
    p.add_argument("--rows", nargs="+", default=["assertive"], help="rows (SUMO drivers)")
    p.add_argument("--seeds", type=int, nargs="+", default=[0, 1, 2], help="training seeds")
    p.add_argument("--round-episodes", type=int, default=4, help="learner-driven episodes per road")
    p.add_argument("--rounds", type=int, choices=range(1, 6), default=1, help="DAgger rounds")
    p.add_argument("--episodes", type=int, default=20, help="evaluation episodes per road")
    p.add_argument("--eval-base", type=int, default=styles.EVAL_BASE, help="the drives' episode seed base")
    p.add_argument("--epochs", type=int, default=6, help="stage-1 epochs")
    p.add_argument("--laps", type=int, default=2)
    p.add_argument("--max-cycles", type=int, default=800)
    p.add_argument("--threads", type=int, default=1, help="torch threads of each training")
    p.add_argument("--workers", type=int, default=1, help="episodes collected or driven in parallel")
    styles.add_rule_flags(p)
    a = p.parse_args(argv)
    bad = [d for d in [*a.demonstrators, *a.rows] if d not in styles.CONFIGS]
    if bad or "expert" in a.rows:
        what = f"unknown demonstrator {bad[0]}" if bad else "the expert labels its own rounds already"
        sys.exit(f"style_dagger: {what}: rows are SUMO drivers of {', '.join(styles.CONFIGS)}")
    a.safety, a.rule, a.train_config, a.train_sets = False, rule(a.rounds), "configs/train/stage1.toml", []
    a.drive_tag = styles.drive_tag(commit=a.commit, stop=a.full_stop)
    os.environ.setdefault("OMP_NUM_THREADS", str(a.threads))
    styles.RULES[a.rule] = []  # the rounds' data is what differs, not a training setting
    out, at = Path(a.out), "" if a.eval_base == styles.EVAL_BASE else f"-s{a.eval_base}"
    try:
        for d in a.rows:
            data = [out / "data" / d / road for road in a.roads]
            if not all(styles.complete(f) for f in data):
                sys.exit(f"style_dagger: no dataset of {d} in {out}/data: run studies/styles.py first")
            for seed in a.seeds:
                rounds = [f for r in range(1, a.rounds + 1) for f in dagger_round(d, seed, out, a, r)]
                runs = out / "runs" / f"{d}-{a.rule}-seed{seed}"
                styles.train([*data, *rounds], runs, seed, a, [])
                for road in a.roads:
                    folder = out / f"drive{at}{a.drive_tag}" / road / runs.name
                    styles.drive(styles.CONFIGS[d], road, [MODEL], runs, folder, a)
    except subprocess.CalledProcessError as e:  # the command printed its own one line above
        sys.exit(f"style_dagger: step failed (exit {e.returncode}): {' '.join(map(str, e.cmd))}")
    norms = ["--out", str(out), "--roads", *a.roads, "--demonstrators", *a.demonstrators, "--rows", *a.rows]
    norms += ["--seeds", *map(str, a.seeds), "--eval-base", str(a.eval_base), "--rule", a.rule]
    return style_norms.main(norms + ["--commit"] * a.commit + ["--full-stop"] * a.full_stop)


if __name__ == "__main__":
    sys.exit(main())

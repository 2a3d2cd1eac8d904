r"""Time to a reward against quality: every DAgger schedule of the faster recipe tried, a table and a picture.

For every training seed's run of the faster recipe (``<out>/new-seed<s>/`` of ``studies/recipe.py``: its
stage 1, its own DAgger rounds of 6 and 20 learner episodes, and the schedules ``studies/rounds.py`` ran
beside them in ``rounds-<schedule>/``), each schedule whose last round drove the first development sample
(20 episodes of 2 laps from seed 2000) gives one point per model:

- time to a reward: stage 1 plus the schedule's DAgger rounds, with PTACNN+S trained in the last round
  only (``stage2_every_round = false``: the same last-round models; the earlier rounds' stage 2 is
  left out of a schedule that ran it), as recorded by the runs;
- quality: the share of the checkpoints in lane, the safety events (collisions, exits, missed stops)
  and the closed-loop score (mean over the episodes).

``--acceptance <out>/recipe.json`` adds the rows of a ``studies/recipe.py`` run (its own seeds, each
recipe's time as it ran); ``--development`` the rows of development variants' runs on the first
development sample (their ``recipe-s2000.json``, copied aside). The table goes to
``<out>/time-quality.md`` and ``.json``, the picture to ``--picture``:

    .venv/bin/python studies/time_quality.py --out runs/recipe --seeds 10 11 \
        --picture docs/img/recipe_time_quality.png
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path
from typing import Any

sys.path.insert(0, str(Path(__file__).parent))
import recipe  # noqa: E402  (studies/recipe.py: the bar and its cells)
import rounds  # noqa: E402  (studies/rounds.py: a schedule's DAgger time)

from irlsim.drive.metrics import summarize  # noqa: E402

OWN = "6,20 (the recipe)"


def schedule_folders(run: Path) -> list[tuple[str, Path, Path]]:
    """(label, DAgger folder, development drive folder) of every schedule of the run in ``run`` that drove
    the first development sample: the recipe's own rounds first."""
    found = [(OWN, run / "dagger", run / "accept-round2-s2000-e20")]
    for here in sorted(run.glob("rounds-*")):
        label = here.name.removeprefix("rounds-").removesuffix("-s2last").replace("-", ",")
        found.append((label, here, here / "dev20"))
    return [f for f in found if (f[2] / "drive.json").is_file()]


def points(run: Path) -> list[dict[str, Any]]:
    """One row per (schedule, model) of the run in ``run`` (``<out>/new-seed<s>``)."""
    stage1 = float(json.loads((run / "times.json").read_text())["stage 1"])
    rows = []
    for label, here, dev in schedule_folders(run):
        eps = json.loads((dev / "drive.json").read_text())["episodes"]
        minutes = (stage1 + rounds.dagger_seconds(here, stage2_last=True)) / 60
        for m in recipe.MODELS:
            s = summarize([e for e in eps if e["drive/model"] == m])
            rows.append(row(label, int(run.name.rsplit("seed", 1)[1]), m, minutes, "development", s))
    return rows


def row(label: str, seed: int, model: str, minutes: float, seeds: str, s: dict[str, Any]) -> dict[str, Any]:
    """One point: a schedule's model, its time to a reward and the summary ``s`` of its drives."""
    missed = s["drive/stop_lines_passed"] - s["drive/stop_lines_compliant"]
    return {
        "schedule": label, "seed": seed, "model": model, "minutes": round(minutes, 2), "seeds": seeds,
        "in_lane": recipe.in_lane(s), "events": s["drive/collisions"] + s["drive/exits"] + missed,
        "score": s["score/score"], "drive": s,
    }  # fmt: skip


def acceptance_rows(path: Path, seeds: str = "evaluation") -> list[dict[str, Any]]:
    """The rows of a studies/recipe.py run (its ``recipe.json``, or ``recipe-s<seed>.json`` on
    ``seeds="development"``): each recipe as it ran."""
    rows = []
    for r in json.loads(path.read_text()):
        minutes = (r["times"].get("stage 1", 0.0) + r["dagger_s"]) / 60
        rows += [row(r["recipe"], r["seed"], m, minutes, seeds, r["drive"][m]) for m in recipe.MODELS]
    return rows


def table(rows: list[dict[str, Any]]) -> str:
    head = "schedule | drive seeds | seed | model | to a reward [min] | collisions | exits | stops"
    head += " | checkpoints in lane | in lane [%] | score"
    lines = [f"| {head} |", "|" + "---|" * (head.count("|") + 1)]
    for r in rows:
        cells = [r["schedule"], r["seeds"], r["seed"], r["model"], f"{r['minutes']:.1f}"]
        cells += [*recipe.closed_loop_cells(r["drive"]), f"{100 * r['in_lane']:.1f}", f"{r['score']:.1f}"]
        lines.append("| " + " | ".join(map(str, cells)) + " |")
    return "\n".join(lines) + "\n"


def picture(rows: list[dict[str, Any]], path: Path) -> None:
    """Checkpoints in lane against time to a reward, one point per (schedule, seed, model); a ring marks
    a point with a safety event; a hollow point is on evaluation seeds."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(7.5, 4.5), dpi=110)
    labels = list(dict.fromkeys(r["schedule"] for r in rows))
    colours = {k: plt.get_cmap("tab10")(i % 10) for i, k in enumerate(labels)}
    for r in rows:
        marker = "o" if r["model"] == "PACNN+S" else "^"
        face = "none" if r["seeds"] == "evaluation" else colours[r["schedule"]]
        ax.scatter(r["minutes"], 100 * r["in_lane"], marker=marker, s=46, c=[face],
                   edgecolors=[colours[r["schedule"]]], linewidths=1.3)  # fmt: skip
        if r["events"]:
            ax.scatter(
                r["minutes"], 100 * r["in_lane"], marker="o", s=190, facecolors="none", edgecolors="red"
            )
    for k in labels:
        ax.scatter([], [], marker="s", c=[colours[k]], label=k)
    ax.scatter([], [], marker="o", c="grey", label="PACNN+S")
    ax.scatter([], [], marker="^", c="grey", label="PTACNN+S")
    ax.scatter([], [], marker="o", s=190, facecolors="none", edgecolors="red", label="a safety event")
    if any(r["seeds"] == "evaluation" for r in rows):
        ax.scatter([], [], marker="o", facecolors="none", edgecolors="grey", label="hollow: evaluation seeds")
    ax.axhline(100 * recipe.MISSION_BAR, color="k", lw=0.8, ls="--")
    ax.axvline(20, color="k", lw=0.8, ls=":")
    ax.set_xlabel("time to a reward on 2 CPU cores [min] (stage 1 + DAgger)")
    ax.set_ylabel("checkpoints in lane [%]")
    ax.set_title("The faster recipe's DAgger schedules: time against the mission")
    ax.legend(fontsize=7, loc="lower right", ncol=2)
    fig.tight_layout()
    fig.savefig(path)
    plt.close(fig)


def main() -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--out", default="runs/recipe", help="the recipe study's folder (studies/recipe.py)")
    p.add_argument("--seeds", type=int, nargs="+", default=[10, 11], help="training seeds of the runs")
    p.add_argument("--acceptance", help="a studies/recipe.py run's recipe.json to add (evaluation seeds)")
    p.add_argument(
        "--development", nargs="+", default=[],
        help="studies/recipe.py runs of development variants on the first development sample to add "
        "(their recipe-s2000.json, kept under another name: every run writes that name)",
    )  # fmt: skip
    p.add_argument("--picture", help="where to draw the picture (default <out>/time-quality.png)")
    a = p.parse_args()
    out = Path(a.out)
    runs = [out / f"new-seed{s}" for s in a.seeds]
    for run in runs:
        if not (run / "times.json").is_file():
            raise SystemExit(f"{run} has no recorded stage 1: run studies/recipe.py --recipes new first")
    for option, path in [("--acceptance", a.acceptance)] + [("--development", d) for d in a.development]:
        if path and not Path(path).is_file():
            raise SystemExit(f"{option}: {path} is not a file: give a studies/recipe.py run's json")
    rows = [r for run in runs for r in points(run)]
    rows += [r for path in a.development for r in acceptance_rows(Path(path), "development")]
    rows += acceptance_rows(Path(a.acceptance)) if a.acceptance else []
    pic = Path(a.picture) if a.picture else out / "time-quality.png"
    (out / "time-quality.json").write_text(json.dumps(rows, indent=1) + "\n")
    (out / "time-quality.md").write_text(table(rows))
    picture(rows, pic)
    print(table(rows) + f"wrote {out / 'time-quality.md'}, {out / 'time-quality.json'} and {pic}")
    return 0


if __name__ == "__main__":
    sys.exit(main())

r"""The style study's table under both normalisations of the style distance: the definition, the one before.

The style distance (:func:`irlsim.rollout.style.style_distances`, the one definition) divides each figure
by its standard deviation over every *episode* of the demonstrators' own driving (the references'
episodes pooled, :func:`irlsim.rollout.style.style_spread`): a difference counts against how much the
figure varies from one episode to the next among the drivers compared, and the normaliser is the same for
every row of a table. Until 2026-12-01 it divided each figure by its spread over the drivings compared:
the row's driving and the demonstrators' own (four pooled values, "pooled" here). A figure on which the
three demonstrators nearly agree (the stop rate, the middle lane's share) then counted as much as one on
which they differ most, and a row alone on it got the largest normalised difference there whatever its
size; the tables of docs/results/styles.md before "The style distance's normaliser" say "as defined" for
that one.

Reads a ``studies/styles.py`` run (its drives and references; nothing is driven again) and writes, per
road, each row's cells and nearest demonstrator under both, with each figure's two normalisers, and for
every row not nearest its own demonstrator as defined, each figure's signed normalised difference from
its own and from the nearest (what keeps it from its own; the distance is the RMS of these), and for every
row not nearest its own demonstrator under either, its distances as defined with one group of figures
(:data:`GROUPS`) set to its own demonstrator's value in turn (which figure alone keeps it from its own):

    .venv/bin/python studies/style_norms.py --out runs/styles --eval-base 2000 \
        --demonstrators expert cautious assertive --rows cautious assertive \
        [--safety] [--commit] [--full-stop] [--choice]

to ``<out>/style-norms[-s<base>][-safe][-commit][-stop][-choice]-<rows>.md`` and ``.json``.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path
from typing import Any

import numpy as np

sys.path.insert(0, str(Path(__file__).parent))
import styles  # noqa: E402  (studies/styles.py: the study's folders and pooled styles)

from irlsim.rollout.style import (  # noqa: E402
    STYLE_FIGURES,
    pool_styles,
    style_distances,
    style_spread,
    style_vector,
)

#: the two spreads of a figure the table shows: over the references' episodes (the definition), over
#: their pooled values (the definition until 2026-12-01 added the row to these)
EPISODES, POOLED = "references' episodes", "references pooled"
#: the groups of figures the counterfactual sets to the row's own demonstrator's, one at a time
GROUPS = {
    "speed": ("style/mean_speed",),
    "headway": ("style/headway_median_s", "style/headway_p10_s"),
    "lane changes": ("style/lane_changes_per_km",),
    "acceleration, jerk": ("style/rms_accel", "style/rms_jerk"),
    "stops": ("style/stops_per_km",),
    "lane shares": ("style/lane_share",),
}


def figure_names(n_lanes: int) -> list[str]:
    return [f.removeprefix("style/") for f in STYLE_FIGURES] + [f"lane {i} share" for i in range(n_lanes)]


def episode_distances(row: dict[str, Any], refs: list[dict[str, Any]], spread: np.ndarray) -> np.ndarray:
    """[len(refs)] the style distance of the row from each reference, each figure divided by ``spread``
    (:func:`irlsim.rollout.style.style_spread` of the references' episodes): the definition."""
    return style_distances([row, *refs], spread)[0, 1:]


def figure_gaps(row: dict[str, Any], ref: dict[str, Any], spread: np.ndarray) -> np.ndarray:
    """[F] each figure's (row - ref) / spread (NaN where the spread is 0 or either value is NaN): the
    terms whose RMS :func:`episode_distances` is."""
    n_lanes = len(spread) - len(STYLE_FIGURES)
    with np.errstate(invalid="ignore", divide="ignore"):
        gap = (style_vector(row, n_lanes) - style_vector(ref, n_lanes)) / np.where(spread > 0, spread, np.nan)
    return gap


def counterfactual(
    row: dict[str, Any], refs: dict[str, dict[str, Any]], own: str, spread: np.ndarray
) -> dict[str, dict[str, float]]:
    """For each of :data:`GROUPS`: the distances as defined (each figure divided by ``spread``) from
    ``row`` to every reference with that group's figures set to reference ``own``'s."""
    out = {}
    for name, keys in GROUPS.items():
        moved = {**row, **{k: refs[own][k] for k in keys}}
        d = style_distances([moved, *refs.values()], spread)[0, 1:]
        out[name] = dict(zip(refs, map(float, d), strict=True))
    return out


def own_driving(out: Path, d: str, road: str, at: str) -> Path:
    """The file that holds demonstrator ``d``'s own driving on ``road`` (as styles.py drove it): the
    expert's drives, the other demonstrators' collections (any of them, the expert's config too)."""
    if d == "expert":
        return out / f"drive{at}" / road / "expert" / "drive.json"
    return out / f"reference{at}" / d / road / "manifest.json"


def missing_driving(out: Path, demonstrators: list[str], roads: list[str], at: str) -> str | None:
    """The first "<demonstrator> on <road>" whose own driving (:func:`own_driving`) is not in ``out``."""
    return next(
        (f"{d} on {r}" for r in roads for d in demonstrators if not own_driving(out, d, r, at).is_file()),
        None,
    )


def reference_episodes(out: Path, d: str, road: str, at: str) -> list[dict[str, Any]]:
    """The style summaries of demonstrator ``d``'s own episodes on ``road`` (as styles.py drove them)."""
    path = own_driving(out, d, road, at)
    if d == "expert":
        eps = json.loads(path.read_text())["episodes"]
        return [e for e in eps if e.get("style/time_s", 0) > 0]
    return styles.collected_episodes(path.parent)


def road_table(out: Path, road: str, a: Any) -> dict[str, Any]:
    at, safe = a.at, a.drive_tag
    episodes = {d: reference_episodes(out, d, road, at) for d in a.demonstrators}
    refs = {d: pool_styles(e) for d, e in episodes.items()}
    n_lanes = max(len(r["style/lane_share"]) for r in refs.values())
    spread = style_spread([e for eps in episodes.values() for e in eps], n_lanes)
    rows = []
    for d in a.rows:
        tag, _ = styles.learner(d, a)
        for seed in a.seeds:
            dj = out / f"drive{at}{safe}" / road / f"{tag}-seed{seed}" / "drive.json"
            if not dj.is_file():
                raise SystemExit(f"style_norms: {dj} is missing: run studies/styles.py with the same options")
            for m, style in styles.driven_styles(dj).items():
                cols = list(refs)
                pooled = style_distances([style, *refs.values()])[0, 1:]
                per_ep = episode_distances(style, list(refs.values()), spread)
                near = cols[int(np.argmin(per_ep))]
                gaps = {
                    c: [None if np.isnan(x) else float(x) for x in figure_gaps(style, refs[c], spread)]
                    for c in dict.fromkeys([d, near])
                }
                rows.append({
                    "row": f"{m} / {tag} / seed {seed}", "demonstrator": d,
                    "pooled": dict(zip(cols, map(float, pooled), strict=True)),
                    "episodes": dict(zip(cols, map(float, per_ep), strict=True)),
                    "gaps": gaps, "bounds": styles.safety(dj, m),
                })  # fmt: skip
                if cols[int(np.argmin(pooled))] != d or near != d:
                    rows[-1]["counterfactual"] = counterfactual(style, refs, d, spread)
    names = figure_names(n_lanes)
    pooled_spread = np.nanstd(np.stack([style_vector(r, n_lanes) for r in refs.values()]), axis=0)
    both = zip(names, spread, pooled_spread, strict=True)
    figures = {k: {EPISODES: float(s), POOLED: float(p)} for k, s, p in both}
    return {"rows": rows, "spread": figures}


def markdown(tables: dict[str, dict[str, Any]]) -> str:
    parts = []
    for road, t in tables.items():
        cols = list(t["rows"][0]["pooled"]) if t["rows"] else []
        head = ["learned reward", *(f"{c} (as defined)" for c in cols), "own nearest (as defined)"]
        head += [*(f"{c} (pooled)" for c in cols), "own nearest (pooled)", *styles.BOUNDS_HEAD]
        lines = [f"## {road}", "", "| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
        for r in t["rows"]:
            cells = [r["row"]]
            for kind in ("episodes", "pooled"):
                near = min(r[kind], key=r[kind].get)
                cells += [f"**{v:.3f}**" if c == near else f"{v:.3f}" for c, v in r[kind].items()]
                cells.append("yes" if near == r["demonstrator"] else "no")
            lines.append("| " + " | ".join([*cells, *styles.bounds_cells(r["bounds"])]) + " |")
        lines += ["", "| figure | spread over the references' episodes | over the references, pooled |"]
        lines.append("|---|---|---|")
        for k, v in t["spread"].items():
            lines.append(f"| {k} | {v[EPISODES]:.3f} | {v[POOLED]:.3f} |")
        missed = [r for r in t["rows"] if len(r["gaps"]) > 1]
        if missed:
            names = list(t["spread"])
            head = ["row not nearest its own (as defined)", "(row - driver) / spread, driver", *names]
            lines += ["", "| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
            for r in missed:
                for c, g in r["gaps"].items():
                    cells = ["-" if x is None else f"{x:+.2f}" for x in g]
                    lines.append(f"| {r['row']} | {c} | " + " | ".join(cells) + " |")
        lines += counterfactual_lines(t["rows"])
        parts.append("\n".join(lines) + "\n")
    return "\n".join(parts)


def counterfactual_lines(rows: list[dict[str, Any]]) -> list[str]:
    """The counterfactual's table (module docstring): as defined, to its own / to the nearest other."""
    missed = [r for r in rows if "counterfactual" in r]
    if not missed:
        return []
    head = ["row not nearest its own (either): as defined, to own / nearest other", "as measured", *GROUPS]
    lines = ["", "| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    for r in missed:
        cells = [r["row"]]
        for d in (r["episodes"], *r["counterfactual"].values()):
            own = d[r["demonstrator"]]
            other = min(v for c, v in d.items() if c != r["demonstrator"])
            cells.append(f"**{own:.2f}** / {other:.2f}" if own < other else f"{own:.2f} / {other:.2f}")
        lines.append("| " + " | ".join(cells) + " |")
    return lines


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--out", default="runs/styles", help="a studies/styles.py run's folder")
    p.add_argument("--roads", nargs="+", default=[styles.DEFAULT_SCENARIO, "motorway"])
    p.add_argument("--demonstrators", nargs="+", default=["expert", "cautious", "assertive"])
    p.add_argument("--rows", nargs="+", help="demonstrators whose learned rewards get rows (default: all)")
    p.add_argument("--seeds", type=int, nargs="+", default=[0, 1, 2], help="training seeds")
    p.add_argument("--eval-base", type=int, default=styles.EVAL_BASE, help="the drives' episode seed base")
    p.add_argument("--rule", choices=sorted(styles.RULES), default="default")
    p.add_argument("--safety", action="store_true", help="the drives within the planner's label filter")
    p.add_argument(
        "--choice",
        nargs="?",
        const="expected",
        default=None,
        choices=["expected", "maneuver"],
        help="the drives of studies/style_choice.py (with that choice; default: expected)",
    )
    styles.add_rule_flags(p)
    a = p.parse_args(argv)
    a.drive_tag = styles.drive_tag(a.safety, a.commit, a.full_stop, a.choice)
    a.rows = a.rows or a.demonstrators
    unknown = [d for d in [*a.demonstrators, *a.rows] if d not in styles.CONFIGS]
    if unknown:
        sys.exit(f"style_norms: unknown demonstrator {unknown[0]}: choose from {', '.join(styles.CONFIGS)}")
    out = Path(a.out)
    a.at = "" if a.eval_base == styles.EVAL_BASE else f"-s{a.eval_base}"  # the drives' seeds' folders
    if missing := missing_driving(out, a.demonstrators, a.roads, a.at):
        sys.exit(f"style_norms: no driving of {missing} in {out} for these seeds: run studies/styles.py")
    tables = {road: road_table(out, road, a) for road in a.roads}
    name = "style-norms" + a.at
    name += ("" if a.rule == "default" else f"-{a.rule}") + a.drive_tag
    name += "-" + "-".join(a.rows)
    (out / f"{name}.json").write_text(json.dumps(tables, indent=1) + "\n")
    (out / f"{name}.md").write_text(markdown(tables))
    print(markdown(tables) + f"wrote {out / f'{name}.md'} and {out / f'{name}.json'}")
    return 0


if __name__ == "__main__":
    sys.exit(main())

r"""How near a row could come to a driver it cannot match on some figures: the style distance of a
hypothetical row that drives exactly as ``--driver`` on every figure but ``--keep`` (there it has the
mean value of the given rows' drives), from each reference, as defined and pooled (the definition
until 2026-12-01).

Reads a ``studies/styles.py`` run (the references of ``--demonstrators`` on ``--eval-base``'s episodes)
and the drives of ``--rows`` (folders under ``drive[-s<base>][-commit][-stop][-choice]/<road>/``;
``--choice``: ``studies/style_choice.py``'s); drives nothing:

    .venv/bin/python studies/style_floor.py --out runs/styles --eval-base 2000 --driver assertive \
        --rows assertive-sumo-dagger assertive-sumo-dagger2 --commit --full-stop
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).parent))
import style_norms  # noqa: E402
import styles  # noqa: E402

from irlsim.rollout.style import pool_styles, style_distances, style_spread  # noqa: E402


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--out", default="runs/styles", help="a studies/styles.py run's folder")
    p.add_argument("--roads", nargs="+", default=[styles.DEFAULT_SCENARIO, "motorway"])
    p.add_argument("--demonstrators", nargs="+", default=["expert", "cautious", "assertive"])
    p.add_argument("--driver", default="assertive", help="the demonstrator the row copies")
    p.add_argument("--keep", nargs="+", default=["rms_jerk", "rms_accel"], help="figures it cannot copy")
    p.add_argument("--rows", nargs="+", required=True, help="drive folders' names without -seed<s>")
    p.add_argument("--seeds", type=int, nargs="+", default=[0, 1, 2])
    p.add_argument("--eval-base", type=int, default=styles.EVAL_BASE)
    styles.add_rule_flags(p)
    p.add_argument("--choice", action="store_true", help="the drives of studies/style_choice.py")
    a = p.parse_args(argv)
    out, at = Path(a.out), "" if a.eval_base == styles.EVAL_BASE else f"-s{a.eval_base}"
    tag = styles.drive_tag(commit=a.commit, stop=a.full_stop, choice=a.choice)
    if a.driver not in a.demonstrators:
        sys.exit(f"style_floor: --driver {a.driver} is not one of --demonstrators")
    for road in a.roads:
        folders = [
            out / f"drive{at}{tag}" / road / f"{r}-seed{s}" / "drive.json" for r in a.rows for s in a.seeds
        ]
        missing = next((f for f in folders if not f.is_file()), None)
        if missing is not None:
            sys.exit(f"style_floor: {missing} is missing: drive those rows first")
        eps = {d: style_norms.reference_episodes(out, d, road, at) for d in a.demonstrators}
        refs = {d: pool_styles(e) for d, e in eps.items()}
        n_lanes = max(len(r["style/lane_share"]) for r in refs.values())
        spread = style_spread([e for v in eps.values() for e in v], n_lanes)
        drives = [styles.driven_styles(f)["PACNN+S"] for f in folders]
        row = dict(refs[a.driver])
        for k in a.keep:
            row[f"style/{k}"] = float(np.mean([d[f"style/{k}"] for d in drives]))
        per_ep = style_norms.episode_distances(row, list(refs.values()), spread)
        pooled = style_distances([row, *refs.values()])[0, 1:]
        kept = ", ".join(f"{k} {row[f'style/{k}']:.2f}" for k in a.keep)
        print(f"{road}: {a.driver} but {kept} (the rows' mean):")
        for d, e, q in zip(refs, per_ep, pooled, strict=True):
            print(f"  from {d}: as defined {e:.3f}, pooled {q:.3f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())

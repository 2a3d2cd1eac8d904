r"""Does a driving's RMS acceleration and jerk, or its lane changes, depend on the rate it was recorded at?

SUMO alone drives the style study's recording trips (``studies/styles.py``: 60 cars, one every 4 s, one
lap of the default road, SUMO's default driver) twice, at SUMO's default 1 s step and at 0.1 s, each with
its FCD output; the 0.1 s run is also cut to its whole seconds (the same driving recorded at 1 s). Each
is read and resampled to the 0.1 s step as irlsim reads a recording, and every car's RMS acceleration and
jerk are measured at the step (finite differences over 0.1 s) and over :data:`irlsim.rollout.style.
DERIVATIVE_BASE_S` (the style's figures, :func:`irlsim.rollout.style.style_summary`), pooled over the cars
as the style pools episodes. The lane changes per km of every car that can be an ego (its lane as irlsim
reads a recording: from its offset to its route), counting every change, and as maneuvers (a returning
visit of at most :data:`~irlsim.rollout.style.DERIVATIVE_BASE_S` is none,
:func:`irlsim.rollout.style.lane_changes`). ``--driver assertive``: the cars drive with the assertive
SUMO driver's vType (``configs/collect/styles/assertive.toml``) instead of SUMO's default type. About a
minute each:

    .venv/bin/python studies/style_rate.py --out runs/style-rate
    .venv/bin/python studies/style_rate.py --out runs/style-rate --driver assertive
"""

from __future__ import annotations

import argparse
import re
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).parent))
import styles  # noqa: E402  (studies/styles.py: the recording's sizes)
from sumo_alone import sumo_alone  # noqa: E402

from irlsim.config import load_config  # noqa: E402
from irlsim.data.collection import CollectConfig  # noqa: E402
from irlsim.data.demonstrator import demo_vtype  # noqa: E402
from irlsim.data.recorded import ego_track  # noqa: E402
from irlsim.data.recording import load_recording  # noqa: E402
from irlsim.road import load_road  # noqa: E402
from irlsim.road.scenario import DEFAULT_SCENARIO  # noqa: E402
from irlsim.rollout.style import DERIVATIVE_BASE_S, lane_changes, pool_styles, style_summary  # noqa: E402

STEP = 0.1  # [s] the simulation step a recording is resampled to
SECONDS = styles.SIZES["rec_seconds"]  # the study's recording: seconds after the last departure


def driver_vtype(driver: str) -> dict[str, str] | None:
    """The cars' vType attributes: None for SUMO's default type, else the style study's SUMO driver's."""
    if driver == "default":
        return None
    cfg = load_config(CollectConfig, styles.CONFIGS[driver])
    return demo_vtype(cfg.demonstrator, cfg.scenario)


def record(folder: Path, step: float, seed: int, driver: str = "default") -> Path:
    """SUMO alone drives the study's recording trips at ``step`` with its FCD output (once)."""
    fcd = folder / (f"fcd-{step:g}s.xml" if driver == "default" else f"fcd-{driver}-{step:g}s.xml")
    if not fcd.is_file():
        road = load_road(scenario=DEFAULT_SCENARIO)
        sumo_alone(fcd, road, styles.REC_CARS, SECONDS, seed, step, driver_vtype(driver))
    return fcd


def lane_figures(fcd: Path) -> dict[str, float]:
    """Lane changes per km of every car that can be an ego: every change, and as maneuvers."""
    road = load_road(scenario=DEFAULT_SCENARIO)
    rec = load_recording(fcd, road.net, STEP)
    every = maneuvers = 0
    km = 0.0
    for vid in rec.ids:
        et = ego_track(rec, vid, road)
        if isinstance(et, str):
            continue
        lane = et.road.lane_of_d(et.d)
        every += lane_changes(lane, STEP)
        maneuvers += lane_changes(lane, STEP, DERIVATIVE_BASE_S)
        km += float(np.abs(np.diff(et.s)).sum()) / 1000.0
    return {"lc_every": every / km, "lc_maneuvers": maneuvers / km, "km": km}


def whole_seconds(fcd: Path) -> Path:
    """The FCD's timesteps at whole seconds only: the same driving recorded at 1 s."""
    out = fcd.with_name(fcd.stem + "-cut-1s.xml")
    if not out.is_file():
        text = fcd.read_text()
        steps = re.findall(r'<timestep time="([0-9.]+)">.*?</timestep>', text, flags=re.S)
        kept = re.sub(
            r'\s*<timestep time="([0-9.]+)">.*?</timestep>',
            lambda m: m.group(0) if abs(float(m.group(1)) - round(float(m.group(1)))) < 1e-6 else "",
            text,
            flags=re.S,
        )
        out.write_text(kept)
        print(f"{fcd.name}: {len(steps)} timesteps, cut to whole seconds in {out.name}")
    return out


def figures(fcd: Path) -> dict[str, float]:
    """RMS acceleration and jerk of every car, at the step and over the style's base, pooled by time."""
    rec = load_recording(fcd, load_road(scenario=DEFAULT_SCENARIO).net, STEP)
    summaries, step = [], []
    for i in range(len(rec.ids)):
        v = rec.v[rec.start[i] : rec.start[i + 1]]
        if len(v) < 3:
            continue
        t = np.arange(len(v)) * STEP
        summaries.append(
            style_summary(t, np.cumsum(v) * STEP, v, np.zeros(len(v), int), np.full(len(v), np.nan))
        )
        acc = np.diff(v) / STEP
        step.append((float(t[-1]), np.mean(acc**2), np.mean((np.diff(acc) / STEP) ** 2)))
    pooled = pool_styles(summaries)
    w, a2, j2 = (np.array(c) for c in zip(*step, strict=True))
    return {
        "accel_step": float(np.sqrt(np.average(a2, weights=w))),
        "jerk_step": float(np.sqrt(np.average(j2, weights=w))),
        "accel_base": pooled["style/rms_accel"],
        "jerk_base": pooled["style/rms_jerk"],
    }


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--out", default="runs/style-rate", help="the FCD files' folder")
    p.add_argument("--seed", type=int, default=1, help="SUMO's seed (the study's recording: 1)")
    p.add_argument("--driver", default="default", choices=["default", "assertive"], help="the cars' type")
    a = p.parse_args(argv)
    folder = Path(a.out)
    folder.mkdir(parents=True, exist_ok=True)
    fine = record(folder, 0.1, a.seed, a.driver)
    runs = {
        "SUMO at 1 s": record(folder, 1.0, a.seed, a.driver),
        "SUMO at 0.1 s": fine,
        "SUMO at 0.1 s, cut to 1 s rows": whole_seconds(fine),
    }
    base = f"{DERIVATIVE_BASE_S:g} s"
    lines = [
        f"| recorded ({a.driver} driver) | RMS accel at the step / over {base} [m/s^2] "
        f"| RMS jerk at the step / over {base} [m/s^3] | lane changes per km: every / maneuvers | km |",
        "|---|---|---|---|---|",
    ]
    for name, fcd in runs.items():
        f, lanes = figures(fcd), lane_figures(fcd)
        lines.append(
            f"| {name} | {f['accel_step']:.3f} / {f['accel_base']:.3f} "
            f"| {f['jerk_step']:.3f} / {f['jerk_base']:.3f} "
            f"| {lanes['lc_every']:.2f} / {lanes['lc_maneuvers']:.2f} | {lanes['km']:.1f} |"
        )
    print("\n".join(lines))
    name = "rates.md" if a.driver == "default" else f"rates-{a.driver}.md"
    (folder / name).write_text("\n".join(lines) + "\n")
    print(f"wrote {folder / name}")
    return 0


if __name__ == "__main__":
    sys.exit(main())

"""A recording's position noise (a tracker's, a GPS's) and the recorded ego's state: its rates are fitted
over a window (``local_rates``, closed forms: a quadratic's derivatives exactly, white noise's variance as
least squares gives it), and a recording with 0.2 m of noise keeps its demonstrations, which finite
differences lose (real SUMO, real collection); a recorded ego drives on through an overlap of its noisy
positions with another's."""

from __future__ import annotations

import json
import math
import subprocess
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np
import pyarrow as pa
import pyarrow.csv as pacsv
import pyarrow.parquet as pq
import pytest

from irlsim.cli import main
from irlsim.data.recorded import RATE_WINDOW, local_rates
from irlsim.road import load_road
from irlsim.road.network import sumo_binary
from tests.data.test_recording import _collect, _columns, _csv


@pytest.mark.parametrize("n", [3, 7, 21, 200])
def test_the_rates_of_a_quadratic_are_its_derivatives_at_every_sample(n):
    dt = 0.1
    t = np.arange(n) * dt
    first, second = local_rates(1.5 - 0.7 * t + 0.4 * t * t, dt, 2.0)  # windows shrink to fit n
    np.testing.assert_allclose(first, -0.7 + 0.8 * t, atol=1e-9)
    np.testing.assert_allclose(second, np.full(n, 0.8), atol=1e-9)


def test_no_window_is_finite_differences():
    z = np.random.default_rng(0).normal(size=50)
    first, second = local_rates(z, 0.1, 0.0)
    np.testing.assert_array_equal(first, np.gradient(z, 0.1))
    np.testing.assert_array_equal(second, np.gradient(np.gradient(z, 0.1), 0.1))


def test_white_noise_enters_the_rate_as_least_squares_says():
    """A slope fitted over samples k = -h..h, dt apart, of noise sigma has the standard deviation
    sigma / (dt sqrt(sum k^2)); finite differences' is sigma / (dt sqrt 2)."""
    dt, sigma, window = 0.1, 0.2, RATE_WINDOW
    noise = np.random.default_rng(1).normal(0.0, sigma, 100_000)
    first, _ = local_rates(noise, dt, window)
    h = round(window / (2 * dt))
    expected = sigma / (dt * math.sqrt(2 * sum(k * k for k in range(1, h + 1))))
    assert abs(first[h:-h].std() / expected - 1) < 0.03
    assert np.gradient(noise, dt)[1:-1].std() > 15 * expected  # what finite differences give


def _recording(tmp: Path, sigma: float) -> Path:
    """SUMO alone drives six cars round the oval for 60 s at a 0.1 s step (its default driver, lane
    changes for speed), written as the columnar format with ``sigma`` [m] of Gaussian position noise."""
    road = load_road()
    fcd = tmp / "fcd.xml"
    if not fcd.exists():
        cars = "".join(
            f'<vehicle id="car{i}" route="loop" depart="{2 * i}" departLane="{i % 3}" departPos="{40 * i}" '
            'departSpeed="max"/>'
            for i in range(6)
        )
        routes = tmp / "cars.rou.xml"
        routes.write_text(f'<routes><route id="loop" edges="{" ".join(road.edges * 2)}"/>{cars}</routes>')
        cmd = [sumo_binary("sumo"), "-n", str(road.net_file), "-r", str(routes), "--end", "60", "--seed", "1"]
        cmd += ["--step-length", "0.1", "--fcd-output", str(fcd), "--no-step-log", "true"]
        subprocess.run(cmd, check=True, capture_output=True)
    cols: dict[str, list] = {k: [] for k in ("id", "t", "x", "y", "v", "heading")}
    for ts in ET.parse(fcd).getroot().iter("timestep"):
        for v in ts.iter("vehicle"):
            cols["id"].append(v.get("id"))
            cols["t"].append(float(ts.get("time")))
            for k, a in (("x", "x"), ("y", "y"), ("v", "speed")):
                cols[k].append(float(v.get(a)))
            cols["heading"].append(math.radians(90.0 - float(v.get("angle"))))
    rng = np.random.default_rng(7)
    for k in ("x", "y"):
        cols[k] = list(np.asarray(cols[k]) + rng.normal(0.0, sigma, len(cols[k])))
    out = tmp / f"noise{sigma:g}.csv"
    pacsv.write_csv(pa.table(cols), out)
    return out


def _demonstrations(tmp: Path, file: Path, window: float | None) -> int:
    """Cycles with a demonstration of a collection of cars 0 and 1 as egos, 60 cycles each (``window``: the
    rate window, None the default)."""
    name = f"{file.stem}-{window}"
    cfg = tmp / f"{name}.toml"
    cfg.write_text(
        "seed = 0\nworkers = 1\nmax_cycles = 60\ntrain_episodes = 2\nvalidation_episodes = 0\n"
        "test_episodes = 0\n"
        '[planner]\nn_policies = 200\nv_max = 35.0\n[demonstrator]\nkind = "recording"\n'
        f'file = "{file}"\nego = "car0,car1"\n' + ("" if window is None else f"rate_window = {window}\n")
    )
    assert main(["collect", "--config", str(cfg), "--out", str(tmp / name)]) == 0
    return sum(
        int(pq.read_table(p, columns=["has_demo"]).column("has_demo").to_numpy().sum())
        for p in (tmp / name / "train").glob("*.cycles.parquet")
    )


def test_a_noisy_recording_keeps_its_demonstrations(tmp_path):
    clean = _demonstrations(tmp_path, _recording(tmp_path, 0.0), None)
    noisy = _recording(tmp_path, 0.2)
    fitted, differenced = _demonstrations(tmp_path, noisy, None), _demonstrations(tmp_path, noisy, 0.0)
    # two cars, 60 cycles each: shares as of three cars' 100 (0.98 of them fitted, 0.28 differenced)
    assert clean >= 60  # 72 of the 120 cycles here
    assert fitted >= 0.9 * clean  # all 72
    assert differenced < 0.6 * clean  # finite differences, as before the window: 26


def test_a_recorded_ego_drives_on_through_an_overlap_of_its_recorded_positions(fcd, tmp_path):
    """A recording goes on where the ego's recorded box overlaps another's (noisy positions do, side by
    side): the collection counts the collision and keeps the episode to its end, as recorded."""
    cols = _columns(fcd)
    at = {(vid, t): i for i, (vid, t) in enumerate(zip(cols["id"], cols["t"], strict=True))}
    for (vid, t), i in at.items():
        if vid == "veh1" and 5.0 <= t <= 6.0:  # veh1 recorded where veh0 is for a second
            j = at[("veh0", t)]
            cols["x"][i], cols["y"][i] = cols["x"][j], cols["y"][j]
    rc, out = _collect(
        tmp_path, "overlap", f'file = "{_csv(tmp_path / "o.csv", cols)}"\nego = "veh1"\n', train=1
    )
    assert rc == 0
    stats = json.loads((out / "train" / "episode_00000.stats.json").read_text())
    assert stats["sim/collisions"] >= 1 and stats["end_reason"] is None
    assert pq.read_metadata(out / "train" / "episode_00000.cycles.parquet").num_rows == 40

"""OpenDRIVE maps (.xodr, the format of CARLA's and esmini's maps) as a scenario's network: built with
netconvert into the scenario's cache and driven by the expert in real SUMO; a broken map is one line."""

from __future__ import annotations

import json
from pathlib import Path

from irlsim.cli import main
from irlsim.road import load_road

_LANE = (
    '<lane id="{id}" type="{kind}" level="false"><link><{link} id="{id}"/></link>'
    '<width sOffset="0.0" a="{width}" b="0" c="0" d="0"/></lane>'
)


def _road(rid: int, x: float, geometry: str, length: float, link: str) -> str:
    """One OpenDRIVE road: a lane each way on the left, two driving lanes and a sidewalk on the right."""
    other = {"successor": ("2", "start"), "predecessor": ("1", "end")}[link]
    lanes = {
        "left": [(1, "driving", 3.5)],
        "right": [(-1, "driving", 3.5), (-2, "driving", 3.5), (-3, "sidewalk", 2.0)],
    }
    side = {
        k: "".join(_LANE.format(id=i, kind=t, width=w, link=link) for i, t, w in v) for k, v in lanes.items()
    }
    return (
        f'<road name="r{rid}" length="{length}" id="{rid}" junction="-1">'
        f'<link><{link} elementType="road" elementId="{other[0]}" contactPoint="{other[1]}"/></link>'
        f'<planView><geometry s="0.0" x="{x}" y="0.0" hdg="0.0" length="{length}">{geometry}</geometry>'
        f'</planView><lanes><laneSection s="0.0"><left>{side["left"]}</left>'
        f'<center><lane id="0" type="driving" level="false"/></center><right>{side["right"]}</right>'
        "</laneSection></lanes></road>"
    )


def write_xodr(path: Path) -> Path:
    """A 400 m straight into a 300 m curve of radius 500 m, two driving lanes each way but one."""
    roads = _road(1, 0.0, "<line/>", 400.0, "successor") + _road(
        2, 400.0, '<arc curvature="0.002"/>', 300.0, "predecessor"
    )
    path.write_text(
        '<?xml version="1.0" encoding="UTF-8"?>\n<OpenDRIVE><header revMajor="1" revMinor="4" '
        f'name="irlsim test road" version="1.0"/>{roads}</OpenDRIVE>\n'
    )
    return path


def _scenario(folder: Path) -> Path:
    folder.mkdir()
    write_xodr(folder / "road.xodr")
    path = folder / "scenario.toml"
    path.write_text(
        'name = "xodr"\ndescription = "an OpenDRIVE road"\n\n[network]\nopendrive = "road.xodr"\n\n'
        '[route]\nedges = ["-1", "-2"]\n'
    )
    return path


def test_an_opendrive_map_is_built_and_driven_by_the_expert(tmp_path):
    scenario = _scenario(tmp_path / "xodr")
    road = load_road(scenario=str(scenario))
    assert road.n_lanes == 2 and not road.closed  # the driving lanes; the sidewalk is not a car lane
    assert 695.0 < road.route_end_s - road.route_begin_s < 710.0  # 400 m + 300 m, joined at a junction
    out = tmp_path / "sim.json"
    argv = ["sim", "--scenario", str(scenario), "--driver", "expert", "--episodes", "1", "--vehicles", "4"]
    assert main([*argv, "--max-time", "90", "--json", str(out)]) == 0
    (ep,) = json.loads(out.read_text())["episodes"]
    assert ep["end_reason"] == "route_end", ep["end_reason"]
    assert ep["sim/collisions"] == 0 and ep["sim/exits"] == 0 and ep["sim/offroad_steps"] == 0
    assert ep["sim/mean_speed_kmh"] > 30.0


def test_a_broken_opendrive_map_is_one_line(tmp_path, capsys):
    scenario = _scenario(tmp_path / "bad")
    (tmp_path / "bad" / "road.xodr").write_text("<OpenDRIVE><road")  # truncated
    assert main(["scenario", "show", str(scenario)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "netconvert failed on" in err[0] and "fix the OpenDRIVE map" in err[0], err
    assert sorted(p.name for p in (tmp_path / "bad").iterdir()) == [
        "road.xodr",
        "scenario.toml",
    ]  # nothing built

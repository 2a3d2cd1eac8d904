"""``irlsim scenario generate | sweep | check`` on real SUMO networks (no fakes): refusals sorted by reason
as the road layer really words them, a small sweep whose table adds up and reruns as a no-op with the
same bytes, bad input refused in one line before any work, and the acceptance of a shipped scenario."""

from __future__ import annotations

import csv
import json
import os
import subprocess
from pathlib import Path

import pytest

from irlsim.errors import IrlsimError
from irlsim.road import load_road
from irlsim.road.network import sumo_binary, sumo_home
from irlsim.road.refusals import REASON_NAMES, refusal_reason
from irlsim.workflows.scenarios import GenerateRun, generate_networks
from pipelines.commands import main

NODES = "".join(
    f'<node id="{n}" x="{x}" y="0" type="priority"/>'
    for n, x in (
        ("a", 0),
        ("b", 300),
        ("c", 600),
        ("d", 900),
        ("e", 1200),
        ("f", 1300),
        ("g", 1250),
        ("h", 1340),
    )
)
EDGES = (
    '<edge id="ab" from="a" to="b" numLanes="2" speed="13.9" width="3.2"/>'
    '<edge id="bc" from="b" to="c" numLanes="2" speed="13.9" width="3.2"/>'
    '<edge id="cd" from="c" to="d" numLanes="2" speed="13.9" width="3.5"/>'
    '<edge id="de" from="d" to="e" numLanes="2" speed="13.9" width="3.2" sidewalkWidth="2.0"/>'
    '<edge id="ef" from="e" to="f" numLanes="2" speed="13.9" width="3.2"/>'
    '<edge id="fh" from="f" to="h" numLanes="2" speed="13.9" width="3.2"/>'
    '<edge id="dg" from="d" to="g" numLanes="1" speed="5.0" width="3.0" allow="bicycle pedestrian"/>'
)


#: a square ring of 600 m sides, 2 lanes all round: a loop with nothing that derives a checkpoint
RING_NODES = "".join(
    f'<node id="{n}" x="{x}" y="{y}" type="priority"/>'
    for n, x, y in (("a", 0, 0), ("b", 600, 0), ("c", 600, 600), ("d", 0, 600))
)
RING_EDGES = "".join(
    f'<edge id="{a}{b}" from="{a}" to="{b}" numLanes="2" speed="13.9"/>' for a, b in ("ab", "bc", "cd", "da")
)


def _netconvert(folder: Path, name: str, *extra: str, nodes: str = NODES, edges: str = EDGES) -> Path:
    folder.mkdir(exist_ok=True)
    (folder / "n.nod.xml").write_text(f"<nodes>{nodes}</nodes>")
    (folder / "e.edg.xml").write_text(f"<edges>{edges}</edges>")
    out = folder / f"{name}.net.xml"
    cmd = [sumo_binary("netconvert"), "-n", "n.nod.xml", "-e", "e.edg.xml", "-o", out.name, *extra]
    subprocess.run(
        cmd, cwd=folder, check=True, capture_output=True, env={**os.environ, "SUMO_HOME": sumo_home()}
    )
    return out


def _refusal(folder: Path, net: Path, route: str) -> str:
    """The road layer's own one-line refusal of ``route`` (a [route] body) on ``net``; '' if it loads."""
    scn = folder / f"s{len(list(folder.glob('s*.toml')))}.toml"
    scn.write_text(f'[network]\nfile = "{net}"\n\n[route]\n{route}\n')
    try:
        load_road(scenario=str(scn))
    except IrlsimError as e:
        return str(e)
    return ""


def test_reasons_of_real_refusals(tmp_path):
    net = _netconvert(tmp_path, "line")
    assert _refusal(tmp_path, net, 'edges = ["ab", "bc"]') == ""  # the control: a route that loads
    assert _refusal(tmp_path, net, 'edges = ["bc", "cd"]') == ""  # lanes of two widths load
    assert _refusal(tmp_path, net, 'edges = ["cd", "de"]') == ""  # and so do a sidewalk beside car lanes
    assert _refusal(tmp_path, net, 'edges = ["ef"]') == ""  # and a route of 100 m
    cases = {
        'edges = ["cd", "dg"]': "no-car-lane",
        'edges = ["fh"]': "too-short",
        'edges = ["bc", "ab"]': "no-path",
        'from = "bc"\nto = "ab"': "no-path",
    }
    for route, reason in cases.items():
        message = _refusal(tmp_path, net, route)
        assert message.count("\n") == 0 and refusal_reason(message) == reason, (route, message)
    left = _netconvert(tmp_path / "left", "left", "--lefthand")
    assert refusal_reason(_refusal(tmp_path, left, 'edges = ["ab", "bc"]')) == "left-hand"
    ring = _netconvert(tmp_path / "ring", "ring", nodes=RING_NODES, edges=RING_EDGES)
    assert _refusal(tmp_path, ring, 'edges = ["ab", "bc", "cd", "da"]') == ""  # a circuit: any lane
    broken = tmp_path / "broken.net.xml"
    broken.write_bytes(net.read_bytes()[:3000])
    assert refusal_reason(_refusal(tmp_path, broken, 'edges = ["ab", "bc"]')) == "network"
    assert refusal_reason("something nobody foresaw") == "other" and REASON_NAMES[-1] == "other"


@pytest.fixture(scope="module")
def networks(tmp_path_factory):
    """Two generated networks (a grid and a spider), the same bytes from a second generation."""
    out = tmp_path_factory.mktemp("nets")
    paths = generate_networks(GenerateRun(2, out / "a", seed=0))
    again = generate_networks(GenerateRun(2, out / "b", seed=0))
    assert [p.name for p in paths] == ["0000_grid.net.xml", "0001_spider.net.xml"]
    assert [p.read_bytes() for p in paths] == [p.read_bytes() for p in again]
    assert json.loads((out / "a" / "generate.json").read_text())["networks"][1]["kind"] == "spider"
    return out / "a"


def test_routes_are_drawn_per_seed_and_route(networks):
    """Route k depends on (seed, k) alone, is a connected car path of the minimum length, no U-turn."""
    from irlsim.road.draw import MIN_ROUTE_LENGTH, draw_routes, read_network

    net = read_network(networks / "0001_spider.net.xml")
    three = draw_routes(net, 3, seed=5)
    assert draw_routes(net, 2, seed=5) == three[:2] and draw_routes(net, 3, seed=6) != three
    for r in three:
        assert not r.refusal and r.length >= MIN_ROUTE_LENGTH
        for a, b in zip(r.edges, r.edges[1:], strict=False):
            edge_a, edge_b = net.getEdge(a), net.getEdge(b)
            assert edge_b in edge_a.getOutgoing() and edge_b.getToNode() is not edge_a.getFromNode()


def _outputs(out: Path) -> dict[str, bytes]:
    return {name: (out / name).read_bytes() for name in ("sweep.md", "sweep.json", "routes.csv")}


def test_sweep_counts_add_up_and_a_rerun_is_a_no_op(networks, tmp_path, capsys):
    out = tmp_path / "sweep"
    argv = ["scenario", "sweep", str(networks), "--routes", "3", "--drive", "1", "--max-time", "15"]
    argv += ["--seed", "0", "--out", str(out)]
    assert main(argv) == 0
    printed = capsys.readouterr().out
    assert "| loaded |" in printed and str(out / "sweep.md") in printed
    summary = json.loads((out / "sweep.json").read_text())
    c = summary["counts"]
    routes = lambda key: c[key]["routes"]  # noqa: E731
    assert c["networks"] == 2 and routes("drawn") == 6
    assert routes("drawn") == routes("loaded") + routes("refused") + routes("crashed_loading")
    assert sum(v["routes"] for v in summary["refused_by_reason"].values()) == routes("refused")
    assert set(summary["refused_by_reason"]) <= set(REASON_NAMES)
    assert routes("driven") == routes("within_bounds") + routes("outside_bounds") + routes(
        "refused_driving"
    ) + routes("crashed_driving")
    assert routes("driven") == c["loaded"]["networks"]  # one per network that has a route that loads
    assert len(summary["crashes"]) == routes("crashed_loading") + routes("crashed_driving")
    assert sum(g["routes"] for g in summary["crashes_by_error"]) == len(summary["crashes"])
    rows = list(csv.DictReader(io_text(out / "routes.csv")))
    assert len(rows) == 6 and {r["load"] for r in rows} <= {"loaded", "refused", "crash"}
    assert sum(r["driven"] == "True" for r in rows) == routes("driven")
    for r in rows:
        if r["load"] == "loaded":
            assert (out / "scenarios" / r["network"] / f"route_{int(r['route']):04d}.toml").is_file()

    before = _outputs(out)
    stamps = {p: p.stat().st_mtime_ns for p in (out / "records").rglob("*.json")}
    assert main(argv + ["--workers", "2"]) == 0  # resumed with other workers: nothing left to do
    assert _outputs(out) == before
    assert {p: p.stat().st_mtime_ns for p in (out / "records").rglob("*.json")} == stamps
    other = [
        a if a != "0" else "1" for a in argv
    ]  # another --seed into the same --out: one line, nothing done
    assert main(other) == 2 and "holds a sweep with other seed" in capsys.readouterr().err
    assert _outputs(out) == before
    # lose the spider's records (its routes loaded, one driven): the same command, the same bytes
    for p in (out / "records" / "0001_spider").glob("0*.json"):
        p.unlink()
    assert main(argv) == 0
    assert _outputs(out) == before


def io_text(path: Path):
    return path.read_text().splitlines()


def _rc(argv: list[str]) -> int:
    """The command's exit status, argparse's own refusals (which exit) included."""
    try:
        return main(argv)
    except SystemExit as e:
        return int(e.code or 0)


def test_bad_input_is_one_line_before_any_work(networks, tmp_path, capsys):
    not_a_net = tmp_path / "notes.net.xml"
    not_a_net.write_text("hello\n")
    out = tmp_path / "out"
    for source, routes in (
        (tmp_path / "missing", "2"),
        (not_a_net, "2"),
        (Path("README.md"), "2"),
        (tmp_path, "2"),  # a folder whose only network file is not one
        (networks, "0"),
    ):
        assert _rc(["scenario", "sweep", str(source), "--routes", routes, "--out", str(out)]) == 2
        err = capsys.readouterr().err
        assert err.count("\n") == 1 and err.startswith("irlsim: error:"), err
        assert not out.exists()
    assert _rc(["scenario", "generate", "--count", "0", "--out", str(out)]) == 2
    assert capsys.readouterr().err.count("\n") == 1 and not out.exists()


def test_check_a_shipped_scenario(tmp_path, capsys):
    out = tmp_path / "check"
    rc = main(
        ["scenario", "check", "grid", "--episodes", "1", "--max-time", "20", "--seed", "3", "--out", str(out)]
    )
    printed = capsys.readouterr().out
    record = json.loads((out / "check.json").read_text())
    assert rc == (0 if record["meets_bar"] else 1)
    assert record["seeds"] == [3] and record["expert"]["collisions"] == 0
    assert record["expert"]["mean_speed_kmh"] > 10 and record["sumo"]["mean_speed_kmh"] > 10
    assert "| grid | 3 | 0 |" in printed and str(out / "check.md") in printed
    assert (out / "check.md").read_text().startswith("| scenario | seeds |")


def test_the_docs_commands_parse():
    """Every ``irlsim scenario check | sweep | generate`` line of the docs names options that exist."""
    import re
    import shlex

    from pipelines.commands import build_parser

    root = Path(__file__).resolve().parents[2]
    text = "".join(page.read_text() for page in sorted((root / "docs" / "guide").glob("*.md")))
    lines = re.findall(r"irlsim (scenario (?:check|sweep|generate) [^`\n]*)", text)
    assert len(lines) >= 6
    for line in lines:
        args = build_parser("scenario").parse_args(shlex.split(line))
        assert args.action in ("check", "sweep", "generate"), line

"""``irlsim sim`` / ``irlsim net`` in-process: a good run; bad input -> one-line error, exit 2, no file."""

from __future__ import annotations

import json
import shutil
import sys
from pathlib import Path

import pytest

from irlsim.cli import main


def _run(capsys, *argv: str) -> tuple[int, str, str]:
    try:
        rc = main(list(argv))
    except SystemExit as e:  # argparse errors exit from inside the parser
        rc = int(e.code or 0)
    out, err = capsys.readouterr()
    return rc, out, err


def _one_line_error(err: str, *words: str) -> None:
    lines = err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("irlsim: error:"), err
    for w in words:
        assert w in lines[0], lines[0]


def test_sim_writes_figures(capsys, tmp_path):
    out = tmp_path / "sim.json"
    rc, stdout, _ = _run(
        capsys,
        "sim",
        "--episodes",
        "2",
        "--vehicles",
        "4",
        "--max-time",
        "8",
        "--seed",
        "3",
        "--json",
        str(out),
    )
    assert rc == 0 and f"wrote {out}" in stdout
    data = json.loads(out.read_text())
    assert len(data["episodes"]) == 2 and data["summary"]["episodes"] == 2
    ep = data["episodes"][0]
    for key in (
        "sim/laps",
        "sim/collisions",
        "sim/exits",
        "sim/stop_lines_passed",
        "sim/stop_lines_compliant",
        "sim/checkpoints_passed",
        "sim/checkpoints_in_lane",
        "sim/mean_speed_kmh",
        "sim/teleports",
        "sim/steps_per_s",
        "end_reason",
    ):
        assert key in ep
    assert ep["end_reason"] == "timeout" and ep["seed"] == 3 and data["episodes"][1]["seed"] == 4
    assert data["summary"]["sim/steps_per_s"] > 0


def test_net_command(capsys):
    rc, out, _ = _run(capsys, "net")
    assert rc == 0 and "oval.net.xml" in out and "lap_length_m" in out


@pytest.mark.parametrize(
    ("argv", "words"),
    [
        (["--seed", "-1"], ["--seed", "0..2147483647", "got -1"]),
        (["--seed", "2147483648"], ["--seed", "2147483647"]),
        (["--seed", "2147483647", "--episodes", "2"], ["--seed + --episodes - 1 = 2147483648", "2147483647"]),
        (["--episodes", "-2"], ["--episodes"]),
        (["--vehicles", "16"], ["--vehicles", "0..15"]),
        (["--laps", "0"], ["--laps"]),
        (["--driver", "nope"], ["unknown driver", "simple"]),
        (["--bogus"], ["unrecognized arguments", "--bogus"]),
        (["--net", "/nonexistent/oval.net.xml"], ["not found", "irlsim net"]),
    ],
)
def test_sim_bad_input(capsys, tmp_path, argv, words):
    out = tmp_path / "sim.json"
    rc, _, err = _run(capsys, "sim", "--max-time", "1", "--json", str(out), *argv)
    assert rc == 2
    _one_line_error(err, *words)
    assert not out.exists() and list(tmp_path.iterdir()) == []


def test_sim_malformed_net(capsys, tmp_path):
    bad = tmp_path / "bad.net.xml"
    bad.write_text("<net><edge id='A_S1'")
    out = tmp_path / "sim.json"
    rc, _, err = _run(capsys, "sim", "--net", str(bad), "--json", str(out))
    assert rc == 2
    _one_line_error(err, "malformed", "fix or regenerate it")  # a network of the user's: not 'irlsim net'
    assert "irlsim net" not in err and not out.exists()


def test_sim_sumo_missing(capsys, tmp_path, monkeypatch):
    monkeypatch.setitem(sys.modules, "sumo", None)  # `import sumo` (the eclipse-sumo wheel) now fails
    out = tmp_path / "sim.json"
    rc, _, err = _run(capsys, "sim", "--max-time", "1", "--json", str(out))
    assert rc == 2
    _one_line_error(err, "SUMO binaries not found", "make setup")
    assert not out.exists()


def test_sim_gui_without_display(capsys, tmp_path, monkeypatch):
    monkeypatch.delenv("DISPLAY", raising=False)
    monkeypatch.delenv("WAYLAND_DISPLAY", raising=False)
    rc, _, err = _run(capsys, "sim", "--gui", "--max-time", "1")
    assert rc == 2
    _one_line_error(err, "display", "without --gui")


def test_sim_libsumo_missing(capsys, tmp_path, monkeypatch):
    monkeypatch.setitem(sys.modules, "libsumo", None)  # `import libsumo` now fails
    out = tmp_path / "sim.json"
    rc, _, err = _run(capsys, "sim", "--max-time", "1", "--json", str(out))
    assert rc == 2
    _one_line_error(err, "libsumo is not installed", "make setup")
    assert not out.exists()


def test_sim_sumolib_missing(capsys, tmp_path, monkeypatch, road):
    net = tmp_path / "oval.net.xml"  # a copy: load_road caches the Road of the usual path
    shutil.copy(road.net_file, net)
    monkeypatch.setitem(sys.modules, "sumolib", None)
    rc, _, err = _run(capsys, "sim", "--max-time", "1", "--net", str(net))
    assert rc == 2
    _one_line_error(err, "sumolib is not installed", "make setup")


def test_sim_json_unwritable_fails_before_running(capsys, tmp_path):
    blocker = tmp_path / "file.txt"
    blocker.write_text("x")
    cases = [(blocker / "sub" / "sim.json", ["--json", "is a file, not a folder"])]
    if Path("/proc/self").is_dir():  # Linux: no file can be created in /proc, not even by root
        cases.append((Path("/proc/irlsim-test/sim.json"), ["--json", "cannot be written"]))
    for target, words in cases:
        rc, stdout, err = _run(capsys, "sim", "--max-time", "1", "--json", str(target))
        assert rc == 2 and stdout == ""  # no episode ran
        _one_line_error(err, *words)
    assert blocker.read_text() == "x" and list(tmp_path.iterdir()) == [blocker]


def test_plot_cycle_bad_out_fails_before_driving(capsys, tmp_path):
    (tmp_path / "keep.txt").write_text("x")
    rc, stdout, err = _run(capsys, "plot-cycle", "--out", str(tmp_path))
    assert rc == 2 and stdout == ""
    _one_line_error(err, "--out", "is a directory", "cycle.png")
    rc, stdout, err = _run(capsys, "plot-cycle", "--seed", "2147483648", "--out", str(tmp_path / "c.png"))
    assert rc == 2 and stdout == ""
    _one_line_error(err, "--seed", "2147483647")
    assert [p.name for p in tmp_path.iterdir()] == ["keep.txt"]


def test_net_reports_netconvert_error_line(capsys, tmp_path, monkeypatch):
    from irlsim.road import network, scenario

    oval = tmp_path / "oval"  # the default scenario's folder, with a broken edge file
    oval.mkdir()
    for name in ("scenario.toml", "netconvert.cfg", "oval.nod.xml", "oval.edg.xml"):
        shutil.copy(network.SUMO_NET_DIR / "oval" / name, oval / name)
    edg = oval / "oval.edg.xml"
    edg.write_text(edg.read_text().replace('from="S1" to="X1"', 'from="Q9" to="X1"'))
    monkeypatch.setattr(scenario, "SUMO_NET_DIR", tmp_path)
    rc, _, err = _run(capsys, "net")
    assert rc == 2
    _one_line_error(
        err,
        "netconvert failed",
        str(oval / "netconvert.cfg"),
        "Error:",
        "from-node 'Q9' is not known",
        "fix the XML sources",
    )
    assert "Quitting" not in err
    assert not (oval / "oval.net.xml").exists()

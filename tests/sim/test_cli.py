"""``irlsim sim`` / ``irlsim net`` in-process: a good run; bad input -> one-line error, exit 2, no file."""

from __future__ import annotations

import json
import sys

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
        (["--seed", "-1"], ["--seed", ">= 0"]),
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
    _one_line_error(err, "malformed", "irlsim net")
    assert not out.exists()


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

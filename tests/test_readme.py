"""The README's and the docs' commands run as written: the README's quickstart block is
examples/reward_quickstart.py verbatim (tests/reward runs that file); the walkthrough of the guide's "Your
own road network" goes from an OpenStreetMap extract to a learned reward driving it (real netconvert,
SUMO, Parquet and training), that of "Demonstrators and style" from a recording to a learned reward
driving where a car of it drove, and that of a highD recording (slow); every other ``irlsim`` command in a
code block of the README, the guide, the design, the results and the open questions names a command and
options that exist, with values they accept (parsed, not run: most are hours of work)."""

from __future__ import annotations

import re
import shlex
import shutil
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
#: the pages whose commands are parsed; HISTORY.md keeps commands of older versions as they were run
DOC_PAGES = [
    "README.md",
    "docs/open-questions.md",
    "docs/guide/*.md",
    "docs/design/*.md",
    "docs/results/*.md",
]
_COMMAND = re.compile(r"^\s*(?:\S+=\S*\s+|nice -n \d+ |time )*(?:\.venv/bin/)?irlsim ([a-z].*)$")


def block(name: str, page: str = "README.md") -> str:
    m = re.search(rf"<!-- {name}:begin -->\n(.*?)<!-- {name}:end -->", (ROOT / page).read_text(), flags=re.S)
    assert m, f"{page} has no {name} block"
    return m.group(1)


def test_quickstart_block_is_the_example_file():
    code = block("quickstart")
    assert code.startswith("```python\n") and code.endswith("```\n")
    assert (
        code[len("```python\n") : -len("```\n")] == (ROOT / "examples" / "reward_quickstart.py").read_text()
    )


def run_walkthrough(name: str, page: str) -> None:
    """Run the four ``.venv/bin/irlsim`` lines of ``page``'s ``name`` block, as written, each exiting 0."""
    from pipelines.commands import main

    lines = [ln.strip() for ln in block(name, page).splitlines() if ln.strip()]
    assert len(lines) == 4 and all(ln.startswith(".venv/bin/irlsim ") for ln in lines)
    for line in lines:
        assert main(shlex.split(line)[1:]) == 0, line


def test_own_road_commands_run_as_written(tmp_path, monkeypatch, capsys):
    from irlsim.road.scenario import scenario_identity

    shutil.copytree(ROOT / "configs", tmp_path / "configs")
    shutil.copytree(
        ROOT / "examples" / "myroad",
        tmp_path / "examples" / "myroad",
        ignore=shutil.ignore_patterns("*.net.xml"),
    )
    monkeypatch.chdir(tmp_path)
    run_walkthrough("own-road", "docs/guide/your-network.md")
    out = capsys.readouterr().out
    assert "route: 3 edges, open" in out and "lanes_per_stretch" in out
    assert (tmp_path / "myroad.png").is_file()
    # a user's road is named by its content, never its path (irlsim.road.scenario.scenario_identity)
    road = scenario_identity("examples/myroad")
    assert road.startswith("myroad@") and "examples/myroad" not in road
    assert f'"name": "{road}"' in (tmp_path / "data" / "myroad" / "manifest.json").read_text()
    drive = (tmp_path / "runs" / "myroad" / "drive" / "drive.json").read_text()
    assert '"scenario": "examples/myroad"' in drive and "PACNN+S" in drive


def test_own_driver_commands_run_as_written(tmp_path, monkeypatch, capsys):
    import json

    shutil.copytree(ROOT / "configs", tmp_path / "configs")
    shutil.copytree(ROOT / "examples" / "mydriver", tmp_path / "examples" / "mydriver")
    monkeypatch.chdir(tmp_path)
    run_walkthrough("own-driver", "docs/guide/demonstrators.md")
    out = capsys.readouterr().out
    # the recording demonstrated: its cars are the egos, their routes matched without a lane column
    manifest = json.loads((tmp_path / "data" / "mydriver" / "manifest.json").read_text())
    record = manifest["demonstrator"]
    assert record["kind"] == "recording" and record["file"] == "examples/mydriver/recording.csv"
    assert record["egos"] == ["car0", "car1", "car2", "car3"]
    assert "demonstrator: recording examples/mydriver/recording.csv" in out
    assert (tmp_path / "runs" / "mydriver" / "stage1" / "PACNN+S" / "checkpoint.pt").is_file()
    # the learned reward drove the held-out car's recording, and the styles were compared
    drive = json.loads((tmp_path / "runs" / "mydriver" / "drive" / "drive.json").read_text())
    assert drive["config"]["recording"]["egos"] == ["car4"]
    assert [s["drive/model"] for s in drive["summary"]] == ["expert", "PACNN+S", "demonstrator"]
    heads = ("style: ", "expert: style", "PACNN+S: style", "demonstrator: style")
    styles = [ln for ln in out.splitlines() if ln.startswith(heads)]
    assert len(styles) >= 4 and "PACNN+S vs demonstrator" in out  # the distance to the recorded driver
    assert "nearest the demonstrator's style: " in out


@pytest.mark.slow
def test_city_recording_commands_run_as_written(tmp_path, monkeypatch, capsys):
    """SUMO's own traffic on its Ingolstadt network, recorded by SUMO, learned and driven reactively."""
    import json
    import subprocess
    import sys

    shutil.copytree(ROOT / "configs", tmp_path / "configs")
    shutil.copytree(
        ROOT / "examples" / "city",
        tmp_path / "examples" / "city",
        ignore=shutil.ignore_patterns("*.net.xml", "*.fcd.xml.gz"),
    )
    monkeypatch.chdir(tmp_path)
    subprocess.run([sys.executable, "examples/city/record.py"], check=True, capture_output=True)
    run_walkthrough("city", "docs/guide/demonstrators.md")
    out = capsys.readouterr().out
    record = json.loads((tmp_path / "data" / "city" / "manifest.json").read_text())["demonstrator"]
    assert record["kind"] == "recording" and len(record["egos"]) >= 5 and "1_horizontal.3" in record["egos"]
    assert record["vehicle_types"][0]["path"] == "sumo_tools/game/fkk_in/fkk_in.rou.xml"
    assert "of another class than a car" in out  # the game's bicycles, by their type
    drive = json.loads((tmp_path / "runs" / "city" / "drive" / "drive.json").read_text())
    assert drive["config"]["recording"]["egos"] == ["1_horizontal.3"]
    assert drive["config"]["recording"]["vehicle_types"] == ["sumo_tools/game/fkk_in/fkk_in.rou.xml"]
    assert [s["drive/model"] for s in drive["summary"]] == ["expert", "PACNN+S", "demonstrator"]
    assert "nearest the demonstrator's style: " in out


@pytest.mark.slow
def test_highd_commands_run_as_written(tmp_path, monkeypatch, capsys):
    """A recording in highD's layout (SUMO's run, examples/highd/sample.py) imported, its cars collected at
    their recorded sizes, learned, and a held-out car driven, each command as the guide writes it."""
    import json
    import subprocess
    import sys

    shutil.copytree(ROOT / "configs", tmp_path / "configs")
    shutil.copytree(ROOT / "examples" / "highd", tmp_path / "examples" / "highd")
    monkeypatch.chdir(tmp_path)
    cmd = [sys.executable, "examples/highd/sample.py", "--out", "data/highd-sample"]
    subprocess.run(cmd, check=True, capture_output=True)
    run_walkthrough("highd", "docs/guide/demonstrators.md")
    out = capsys.readouterr().out
    assert "lower carriageway: 12 vehicles, egos 8 cars and 4 trucks" in out
    record = json.loads((tmp_path / "data" / "highd01-lower" / "manifest.json").read_text())["demonstrator"]
    assert record["ego_size"] == "recorded" and record["position"] == "centre"
    drive = json.loads((tmp_path / "runs" / "highd01-lower" / "drive" / "drive.json").read_text())
    assert [s["drive/model"] for s in drive["summary"]] == ["expert", "PACNN+S", "demonstrator"]
    assert "nearest the demonstrator's style: " in out


@pytest.mark.slow
def test_from_sumo_commands_run_as_written(tmp_path, monkeypatch, capsys):
    """SUMO's game crossing (its demo), run by SUMO alone from its configuration and recorded, imported;
    its cars collected, learned, and a held-out car driven, each command as the guide writes it."""
    import json

    shutil.copytree(ROOT / "configs", tmp_path / "configs")
    monkeypatch.chdir(tmp_path)
    run_walkthrough("from-sumo", "docs/guide/demonstrators.md")
    out = capsys.readouterr().out
    made = json.loads((tmp_path / "data" / "cross" / "from-sumo.json").read_text())
    manifest = json.loads((tmp_path / "data" / "cross-demos" / "manifest.json").read_text())
    assert manifest["demonstrator"]["kind"] == "recording" and made["egos"] >= 4
    drive = json.loads((tmp_path / "runs" / "cross" / "drive" / "drive.json").read_text())
    assert [s["drive/model"] for s in drive["summary"]] == ["expert", "PACNN+S", "demonstrator"]
    assert "nearest the demonstrator's style: " in out


def documented_commands(text: str) -> list[str]:
    """The ``irlsim ...`` lines of a page's code blocks (fenced or indented), continuations joined, comments
    dropped."""
    found, fenced, lines = [], False, text.splitlines()
    i = 0
    while i < len(lines):
        line = lines[i]
        if line.lstrip().startswith("```"):
            fenced = not fenced
        m = _COMMAND.match(line) if fenced or line.startswith("    ") else None
        if m:
            command = m.group(1)
            while command.rstrip().endswith("\\") and i + 1 < len(lines):
                i += 1
                command = command.rstrip()[:-1] + " " + lines[i].strip()
            found.append(re.split(r"\s+#", command)[0])
        i += 1
    return found


def test_documented_commands_parse():
    from pipelines.commands import build_parser

    pages = [p for pattern in DOC_PAGES for p in sorted(ROOT.glob(pattern))]
    commands = [(p, c) for p in pages for c in documented_commands(p.read_text())]
    assert len({p for p, _ in commands}) >= 15 and len(commands) >= 80
    for page, command in commands:
        if "$" in command or "..." in command:  # a template (shell variables, elided models), not a command
            continue
        argv = shlex.split(command)
        try:
            build_parser(argv[0]).parse_args(argv)
        except SystemExit:
            raise AssertionError(f"{page.relative_to(ROOT)}: irlsim {command}") from None

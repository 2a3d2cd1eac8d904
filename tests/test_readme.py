"""The README's code runs as written: the quickstart block is examples/reward_quickstart.py verbatim
(tests/reward runs that file), and the own-road walkthrough's commands go from an OpenStreetMap extract
to a learned reward driving it (real netconvert, SUMO, Parquet and training)."""

from __future__ import annotations

import re
import shlex
import shutil
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
README = (ROOT / "README.md").read_text()


def block(name: str) -> str:
    m = re.search(rf"<!-- {name}:begin -->\n(.*?)<!-- {name}:end -->", README, flags=re.S)
    assert m, f"README has no {name} block"
    return m.group(1)


def test_quickstart_block_is_the_example_file():
    code = block("quickstart")
    assert code.startswith("```python\n") and code.endswith("```\n")
    assert (
        code[len("```python\n") : -len("```\n")] == (ROOT / "examples" / "reward_quickstart.py").read_text()
    )


def test_own_road_commands_run_as_written(tmp_path, monkeypatch, capsys):
    from pipelines.commands import main

    shutil.copytree(ROOT / "configs", tmp_path / "configs")
    shutil.copytree(
        ROOT / "examples" / "myroad",
        tmp_path / "examples" / "myroad",
        ignore=shutil.ignore_patterns("*.net.xml"),
    )
    monkeypatch.chdir(tmp_path)
    lines = [ln.strip() for ln in block("own-road").splitlines() if ln.strip()]
    assert len(lines) == 4 and all(ln.startswith(".venv/bin/irlsim ") for ln in lines)
    for line in lines:
        argv = shlex.split(line)[1:]
        assert main(argv) == 0, line
    out = capsys.readouterr().out
    assert "route: 3 edges, open" in out and "lanes_per_stretch" in out
    assert (tmp_path / "myroad.png").is_file()
    assert '"name": "examples/myroad"' in (tmp_path / "data" / "myroad" / "manifest.json").read_text()
    drive = (tmp_path / "runs" / "myroad" / "drive" / "drive.json").read_text()
    assert '"scenario": "examples/myroad"' in drive and "PACNN+S" in drive

"""The cars-and-trucks study end to end at toy sizes (studies/highd_classes.py): SUMO's run written in
highD's layout, imported, each class learned at its recorded size and driven, with the control that drives
each class's rewards on the other's egos; the table has a row per reward, a finite cell per reference."""

from __future__ import annotations

import json
import math

import pytest

from tests.studies.test_styles import _study

study = _study("highd_classes")


@pytest.mark.slow
def test_toy_study_writes_both_tables(tmp_path):
    argv = ["--out", str(tmp_path), "--vehicles", "30", "--learned", "4", "--driven", "2", "--seeds", "0"]
    assert study.main([*argv, "--epochs", "1", "--cross"]) == 0
    tables = json.loads((tmp_path / "table-cross.json").read_text())
    assert len(tables) == 2
    for table in tables.values():
        assert sorted(r["demonstrator"] for r in table["rows"]) == ["cars", "trucks"]
        for r in table["rows"]:
            assert list(r["cells"]) == ["cars", "trucks", "expert"]
            assert all(math.isfinite(v) and v >= 0 for v in r["cells"].values())
    made = json.loads((tmp_path / "data" / "trucks" / "manifest.json").read_text())["demonstrator"]
    assert made["ego_classes"] == ["truck"] and made["ego_size"] == "recorded"

"""studies/style_choice.py refuses a drive folder that holds another model's drives (it reused them)."""

from __future__ import annotations

import importlib.util
import json
from pathlib import Path

_spec = importlib.util.spec_from_file_location(
    "style_choice", Path(__file__).parents[2] / "studies" / "style_choice.py"
)
study = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(study)  # type: ignore[union-attr]


def test_a_folder_of_another_models_drives_is_refused(tmp_path):
    assert study.other_model(tmp_path, "LIRL") is None  # nothing driven yet
    episodes = [{"drive/model": "PACNN+S", "episode": i} for i in range(2)]
    (tmp_path / "drive.json").write_text(json.dumps({"episodes": episodes}))
    assert study.other_model(tmp_path, "PACNN+S") is None  # its own drives: reused
    why = study.other_model(tmp_path, "LIRL")
    assert why is not None and "holds PACNN+S's drives, not LIRL's" in why

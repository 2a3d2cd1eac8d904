"""A study's recording egos: their configs (collect, drive and reference, the driven egos as recorded)
and their reactive drives, shared by the studies that learn from an imported recording."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import styles  # studies/styles.py: run, irlsim, driven_models

#: the recording rows' rules of the style study (studies/recording_dataset.py)
RULES = ["--full-stop", "--keep-distance", "0.3", "--in-lane"]


def ego_configs(
    tables: dict[str, Any], learned: list[str], driven: list[str], folder: Path, prefix: str = ""
) -> tuple[str, str, str]:
    """(collect, drive, reference) configs of a recording's egos in ``folder`` (``<prefix><name>.toml``):
    ``tables`` (scenario, planner, demonstrator) with the ``learned`` egos collected (two of them to
    validation and test), the ``driven`` ones driven, and, as recorded, the reference."""
    out = []
    for name, ids, splits in (
        ("collect", learned, (len(learned) - 2, 1, 1)),
        ("drive", driven, None),
        ("reference", driven, (len(driven), 0, 0)),
    ):
        tables["demonstrator"] = {**tables["demonstrator"], "ego": ",".join(ids)}
        head = "seed = 0\nmax_cycles = 800\n"
        if splits:
            head += "".join(
                f"{k}_episodes = {n}\n" for k, n in zip(("train", "validation", "test"), splits, strict=True)
            )
        body = "".join(
            f"\n[{t}]\n" + "".join(f"{k} = {json.dumps(v)}\n" for k, v in values.items())
            for t, values in tables.items()
        )
        path = folder / f"{prefix}{name}.toml"
        path.write_text(head + body)
        out.append(str(path))
    return out[0], out[1], out[2]


def drive(config: str, runs: Path | None, models: list[str], out: Path, a: Any) -> Path:
    """``irlsim drive --reactive`` of ``models`` on the driven egos (the learned rewards with the
    recording rows' rules)."""
    if not set(models) <= styles.driven_models(out / "drive.json"):
        styles.run(
            [styles.irlsim(), "drive", *(["--runs", str(runs)] if runs else []), "--model", ",".join(models)]
            + ["--reactive", *(RULES if runs else []), "--episodes", str(a.driven), "--config", config]
            + ["--max-cycles", "800", "--frames", "0", "--workers", str(a.workers), "--out", str(out)]
        )
    return out / "drive.json"

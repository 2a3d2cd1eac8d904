"""The configs of a recording's egos for a study: collect, drive and reference (the driven egos as
recorded), shared by the studies that learn from an imported recording."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any


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

"""What the importers of recordings share (``irlsim scenario from-highd``, ``from-sumo``): writing into a
staging folder that becomes the output only when everything is written, and the split of a recording's
egos into those collected and those driven."""

from __future__ import annotations

import json
import os
import shutil
import tempfile
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

from irlsim.errors import IrlsimError
from irlsim.outputs import check_output_dir
from irlsim.utils import owned_output

#: the fewest egos an import writes configs for (one each to train, validate, test and drive)
MIN_EGOS = 4


@contextmanager
def staged(out: Path, command: str) -> Iterator[Path]:
    """A folder to write an import into; its files move into ``out`` when the block ends without an error,
    none otherwise (``out`` is left as it was; one this import made is removed). An import of the same
    input with the same options gives the same bytes, so a file of ``out`` with other bytes is another
    import's: one line, nothing moved."""
    check_output_dir(out, "--out")
    made = not out.exists()
    out.mkdir(parents=True, exist_ok=True)
    try:
        with owned_output(out, f"scenario {command}"):
            stage = Path(tempfile.mkdtemp(dir=out, prefix=f".{command}-"))
            try:
                yield stage
                files = sorted(stage.iterdir())
                changed = [f.name for f in files if _differs(out / f.name, f)]
                if changed:
                    raise IrlsimError(
                        f"--out {out} holds {changed[0]} of another import (or edited): choose another "
                        "--out, or remove the files of the one there"
                    )
                for f in files:
                    os.replace(f, out / f.name)
            finally:
                shutil.rmtree(stage, ignore_errors=True)
    except BaseException:
        if made:
            shutil.rmtree(out, ignore_errors=True)
        raise


def _differs(target: Path, made: Path) -> bool:
    """Whether ``target`` exists with other bytes than ``made``."""
    return target.is_file() and target.read_bytes() != made.read_bytes()


def split_egos(chosen: list[str]) -> tuple[list[str], list[str], int]:
    """``chosen`` egos (in the order they entered) -> (the first nine in ten, collected; the last tenth,
    driven; how many of the collected go to validation and to test, each)."""
    held = max(1, len(chosen) // 10)
    learned, driven = chosen[: len(chosen) - held], chosen[len(chosen) - held :]
    return learned, driven, max(1, len(learned) // 10)


def ego_configs(
    head: str, kind: str, chosen: list[str], common: str
) -> tuple[dict[str, str], list[str], list[str]]:
    """The collect and drive configs' texts of ``chosen`` egos (``kind``, plural: "cars"), split by
    :func:`split_egos`: ``head`` (a comment line) and ``common`` (their scenario, planner and
    demonstrator tables) around each one's episodes and egos; and the egos collected and driven."""
    learned, driven, test = split_egos(chosen)
    texts = {
        "collect": (
            f"{head}: its first {len(learned)} {kind}, each an ego in turn\nseed = 0\n"
            f"train_episodes = {len(learned) - 2 * test}\nvalidation_episodes = {test}\n"
            f"test_episodes = {test}\n\n{common}ego = {json.dumps(','.join(learned))}\n"
        ),
        "drive": (
            f"{head}: the {len(driven)} {kind} no collected episode used\nseed = 0\n\n{common}"
            f"ego = {json.dumps(','.join(driven))}\n"
        ),
    }
    return texts, learned, driven

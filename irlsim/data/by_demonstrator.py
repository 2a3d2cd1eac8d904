"""Datasets of several demonstrators: which demonstrator every episode (and cycle) is of, selections of
demonstrators (``--demonstrator-select``) with what identifies the selected data, as
:mod:`irlsim.data.roads` does for scenarios.

A folder is the data of one demonstrator (its manifest's ``demonstrator``; none: the expert), named by
:func:`irlsim.data.demonstrator.identity`; an aggregate of folders (``--data A B``) holds several. A
selection keeps the folders of the demonstrators named (an identity, or a kind: ``expert``, ``sumo``,
``recording``: every folder of that kind), and its identity is the sha256 of the whole data's identity and
the selected identities (a training resumed on another selection is refused; evaluation accepts a model
trained on any selection of the data's demonstrators).
"""

from __future__ import annotations

import hashlib
import json
from collections.abc import Sequence
from typing import Any

from irlsim.data.demonstrator import KINDS, identity, identity_kind
from irlsim.errors import IrlsimError


def dataset_demonstrator(dataset: Any) -> str:
    """The identity of the demonstrator of a folder (a :class:`~irlsim.data.reader.Dataset`)."""
    return identity((dataset.manifest or {}).get("demonstrator"))


def known_demonstrators(parts: Sequence[Any]) -> list[str]:
    """The folders' demonstrators, each once, in folder order."""
    return list(dict.fromkeys(dataset_demonstrator(d) for d in parts))


def check_demonstrators(where: str, known: Sequence[str], names: Sequence[str]) -> tuple[str, ...]:
    """The identities ``names`` select (an identity, or a kind naming all of its kind), sorted, without
    repeats; one line (before any work) for a name no folder has."""
    chosen: list[str] = []
    for name in names:
        hits = [k for k in known if name in (k, identity_kind(k))]
        if not hits:
            raise IrlsimError(
                f"datasets {where} have no demonstrator '{name}': --demonstrator-select takes "
                f"{', '.join(known)} or a kind ({', '.join(KINDS)}; irlsim data info lists them)"
            )
        chosen += hits
    return tuple(sorted(set(chosen)))


def demonstrator_selection_identity(whole: str | None, chosen: Sequence[str]) -> str:
    """What identifies a selection of demonstrators in a checkpoint: the sha256 of the whole data's
    identity ``whole`` and the selected identities."""
    key = json.dumps({"dataset": whole, "demonstrators": sorted(chosen)}, separators=(",", ":"))
    return "sha256:" + hashlib.sha256(key.encode()).hexdigest()

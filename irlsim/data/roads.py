"""The roads of a dataset, from its manifest: which scenario every episode was collected on, and
selections of scenarios (``--scenario-select``) with what identifies the selected data. (A scenario
itself, the road's file, is :mod:`irlsim.road.scenario`.)

A dataset over several scenarios (collect config ``[[scenarios]]``) records ``scenarios`` {name: sha256
of its scenario file and network} and ``episode_scenarios`` {split: {episode: name}}; a dataset of one
scenario other than the oval records ``scenarios`` alone, and an oval dataset neither (its scenario is
its config's ``scenario.name``, absent for the oval). See docs/guide/scenarios.md.
"""

from __future__ import annotations

import hashlib
import itertools
import json
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from irlsim.errors import IrlsimError
from irlsim.road.scenario import (
    DEFAULT_SCENARIO,
    Scenarios,
    scenario_identity,
)  # DEFAULT: of a manifest naming none

#: evaluation accepts a model trained on any selection of a dataset's scenarios: up to this many of them
MAX_SELECTABLE = 8


def manifest_scenarios(manifest: dict[str, Any]) -> list[str]:
    """The dataset's scenarios in collection order."""
    recorded = manifest.get("scenarios")
    if isinstance(recorded, dict) and recorded:
        return list(recorded)
    scn = (manifest.get("config") or {}).get("scenario") or {}
    return [str(scn.get("name", DEFAULT_SCENARIO))]


def records_scenarios(manifest: dict[str, Any]) -> bool:
    """Whether the manifest records its roads (several scenarios, or one other than the oval)."""
    return isinstance(manifest.get("scenarios"), dict)


def episode_scenario(manifest: dict[str, Any], split: str, episode: int) -> str:
    """The scenario episode ``episode`` of ``split`` was collected on."""
    per = (manifest.get("episode_scenarios") or {}).get(split)
    if isinstance(per, dict):
        name = per.get(str(episode))
        if name is not None:
            return str(name)
    return manifest_scenarios(manifest)[0]


def by_identity(d: dict[str, Any], scenarios: Scenarios | None = None) -> dict[str, Any]:
    """The config's scenario names as their identities (:func:`irlsim.road.scenario.scenario_identity`):
    the same road spelled another way is the same data config, and no path enters it. ``scenarios``: the
    command's, which has read the roads (None: read here)."""
    identity = (scenarios or Scenarios()).identity
    scn = d.get("scenario")
    if isinstance(scn, dict) and isinstance(scn.get("name"), str):
        d = {**d, "scenario": {**scn, "name": identity(scn["name"])}}
    if d.get("scenarios"):
        d = {**d, "scenarios": [{**e, "name": identity(e["name"])} for e in d["scenarios"]]}
    return d


def parse_selection(
    text: str | None, option: str = "--scenario-select", what: str = "scenario names"
) -> tuple[str, ...] | None:
    """``A,B`` -> ('A', 'B'); None stays None; an empty name is one line naming the option."""
    if text is None:
        return None
    names = tuple(n.strip() for n in text.split(","))
    if not all(names):
        raise IrlsimError(f"{option} {text!r} has an empty name: give {what} separated by commas")
    return names


def check_selection(where: Path | str, known: Sequence[str], names: Sequence[str]) -> tuple[str, ...]:
    """``names`` sorted and without repeats; one line (before any work) when one is not a scenario of
    the dataset(s) ``where``. A name spelled otherwise (a shipped scenario's path, a scenario file) is
    taken as its identity, as the dataset records it."""
    names = [_as_recorded(n, known) for n in names]
    unknown = [n for n in names if n not in known]
    if unknown or not names:
        raise IrlsimError(
            f"dataset {where} has no scenario '{unknown[0] if unknown else ''}': --scenario-select takes "
            f"{', '.join(known)} (irlsim data info lists them)"
        )
    return tuple(sorted(set(names)))


def _as_recorded(name: str, known: Sequence[str]) -> str:
    if name in known:
        return name
    try:
        return scenario_identity(name)
    except IrlsimError:  # no scenario of that name: named as unknown
        return name


def selection_identity(manifest: dict[str, Any], selection: Sequence[str]) -> str:
    """What identifies a selection of a dataset's scenarios in a checkpoint: the sha256 of its manifest's
    identity and the selected names (a training resumed on another selection is refused)."""
    text = json.dumps(manifest, sort_keys=True, separators=(",", ":"), default=str)
    whole = "sha256:" + hashlib.sha256(text.encode()).hexdigest()
    key = json.dumps({"dataset": whole, "scenarios": sorted(selection)}, separators=(",", ":"))
    return "sha256:" + hashlib.sha256(key.encode()).hexdigest()


def selection_key(selection: Sequence[str]) -> str:
    """A short folder name for a selection's cache."""
    return "scenarios-" + hashlib.sha256(json.dumps(sorted(selection)).encode()).hexdigest()[:12]


def selections(names: Sequence[str]) -> list[tuple[str, ...]]:
    """Every non-empty selection of ``names`` (none beyond ``MAX_SELECTABLE`` names)."""
    if len(names) > MAX_SELECTABLE:
        return []
    ordered = sorted(names)
    return [c for k in range(1, len(ordered) + 1) for c in itertools.combinations(ordered, k)]


@dataclass(frozen=True)
class ScenarioEpisodes:
    """One entry of a collect config's ``[[scenarios]]``: a scenario and its episodes per split."""

    name: str = ""
    """a shipped scenario (``irlsim scenario list``) or the path of a scenario.toml"""
    train_episodes: int = 0
    validation_episodes: int = 0
    test_episodes: int = 0

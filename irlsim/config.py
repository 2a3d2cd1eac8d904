"""Typed, validated configuration: nested frozen dataclasses loaded from TOML.

Every stage has one config dataclass; fields carry units in their comments and SI units inside.
``load_config(cls, path)`` rejects unknown keys (naming them), wrong types and out-of-range values with
an :class:`~irlsim.errors.IrlsimError`, so a typo never silently falls back to a default.
"""

from __future__ import annotations

import argparse
import copy
import dataclasses
import math
import os
import tomllib
import types
import typing
from pathlib import Path
from typing import Any, TypeVar

from irlsim.errors import IrlsimError

T = TypeVar("T")


def _convert(tp: Any, value: Any, where: str) -> Any:
    origin = typing.get_origin(tp)
    if dataclasses.is_dataclass(tp) and isinstance(tp, type):
        if isinstance(value, tp):
            return value
        if not isinstance(value, dict):
            raise IrlsimError(f"config: '{where}' must be a table, got {type(value).__name__}")
        return from_dict(tp, value, where)
    if origin in (typing.Union, types.UnionType):
        args = typing.get_args(tp)
        if value is None and type(None) in args:
            return None
        errors = []
        for a in args:
            if a is type(None):
                continue
            try:
                return _convert(a, value, where)
            except IrlsimError as e:  # try the next member of the union
                errors.append(str(e))
        raise IrlsimError(errors[0] if errors else f"config: '{where}' has an invalid value {value!r}")
    if origin in (tuple, list):
        if not isinstance(value, (list, tuple)):
            raise IrlsimError(f"config: '{where}' must be a list, got {value!r}")
        args = typing.get_args(tp)
        if origin is tuple and args and args[-1] is not Ellipsis:
            if len(args) != len(value):
                raise IrlsimError(f"config: '{where}' must have {len(args)} entries, got {len(value)}")
            return tuple(
                _convert(a, v, f"{where}[{i}]") for i, (a, v) in enumerate(zip(args, value, strict=True))
            )
        inner = args[0] if args else Any
        out = [_convert(inner, v, f"{where}[{i}]") for i, v in enumerate(value)]
        return tuple(out) if origin is tuple else out
    if tp is Any:
        return value
    if tp is float:
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            raise IrlsimError(f"config: '{where}' must be a number, got {value!r}")
        if not math.isfinite(value):  # no irlsim config field has a meaning for nan or inf
            raise IrlsimError(f"config: '{where}' must be a finite number, got {value!r}")
        return float(value)
    if tp is int:
        if isinstance(value, bool) or not isinstance(value, int):
            raise IrlsimError(f"config: '{where}' must be an integer, got {value!r}")
        return value
    if tp is bool:
        if not isinstance(value, bool):
            raise IrlsimError(f"config: '{where}' must be true or false, got {value!r}")
        return value
    if tp is str:
        if not isinstance(value, str):
            raise IrlsimError(f"config: '{where}' must be a string, got {value!r}")
        return value
    return value


def from_dict(cls: type[T], data: dict[str, Any], where: str = "") -> T:
    """Build dataclass ``cls`` from a plain dict, recursively; unknown keys are an error."""
    hints = typing.get_type_hints(cls)
    fields = {f.name: f for f in dataclasses.fields(cls)}  # type: ignore[arg-type]
    unknown = sorted(set(data) - set(fields))
    if unknown:
        prefix = f"{where}." if where else ""
        raise IrlsimError(
            f"config: unknown key '{prefix}{unknown[0]}' (known keys: {', '.join(sorted(fields))})"
        )
    kwargs = {}
    for name, value in data.items():
        kwargs[name] = _convert(hints[name], value, f"{where}.{name}" if where else name)
    obj = cls(**kwargs)
    validate = getattr(obj, "validate", None)
    if callable(validate):
        validate()
    return obj


#: dataclass field metadata: the field is left out of :func:`to_dict` while it holds its default (an
#: option added later, so that what an older irlsim wrote with it unset stays byte-identical)
STORED_IF_SET = "stored_if_set"


def to_dict(obj: Any, all_fields: bool = False) -> Any:
    """Dataclass -> plain dict (tuples become lists), suitable for JSON/TOML manifests. A field marked
    ``STORED_IF_SET`` in its metadata is left out while it holds its default (``all_fields``: kept)."""
    if dataclasses.is_dataclass(obj):
        return {
            f.name: to_dict(getattr(obj, f.name), all_fields)
            for f in dataclasses.fields(obj)
            if all_fields or not (f.metadata.get(STORED_IF_SET) and getattr(obj, f.name) == f.default)
        }
    if isinstance(obj, (list, tuple)):
        return [to_dict(v, all_fields) for v in obj]
    return obj


def load_config(
    cls: type[T],
    path: str | Path | None,
    overrides: dict[str, Any] | None = None,
    labels: dict[str, str] | None = None,
    scenarios: Any = None,
) -> T:
    """Load ``cls`` from a TOML file (or defaults when ``path`` is None), then apply ``overrides``.

    Overrides use dotted keys (``{"scenario.n_vehicles": 5}``). A class with a
    ``with_defaults(data, scenarios)`` classmethod fills defaults that depend on the data itself (the
    collect config: a scenario file's ``[defaults]``) before it is built; ``scenarios`` is handed to it
    (the command's :class:`irlsim.road.scenario.Scenarios`: the scenario file read there is the one the
    command goes on with). A bad value is one line naming where it came from: the config file, the
    scenario file's ``[defaults]`` (``defaults_source(data)``) or the override, as ``labels[key]`` names
    it (default ``--set KEY``); see :func:`_blame`.
    """
    data = _read_toml(Path(path)) if path is not None else {}
    full = _with_overrides(data, overrides or {})
    try:
        return _build(cls, full, scenarios=scenarios)
    except IrlsimError as e:
        msg = str(e)
        if not msg.startswith("config: "):  # already names its object (a scenario file, a --set key)
            raise
        source = _blame(cls, data, overrides or {}, labels or {}, path, full)
        if source is None:
            raise
        raise IrlsimError(f"config: {source}: {msg.removeprefix('config: ')}") from None


def _read_toml(p: Path) -> dict[str, Any]:
    if not p.is_file():
        raise IrlsimError(f"config file {p} not found: pass an existing TOML file (see configs/)")
    try:
        return tomllib.loads(p.read_bytes().decode("utf-8"))
    except OSError as e:
        raise IrlsimError(f"config file {p} cannot be read ({e.strerror}): check the path") from None
    except UnicodeDecodeError as e:
        raise IrlsimError(
            f"config file {p} is not UTF-8 text (byte {e.start}): save it as UTF-8 TOML (see configs/)"
        ) from None
    except tomllib.TOMLDecodeError as e:
        raise IrlsimError(f"config file {p} is not valid TOML ({e}): fix the syntax") from None


def _with_overrides(data: dict[str, Any], overrides: dict[str, Any]) -> dict[str, Any]:
    """``data`` (a copy of every table on the way) with the dotted-key ``overrides`` set."""
    data = copy.deepcopy(data)
    for key, value in overrides.items():
        node = data
        parts = key.split(".")
        for i, part in enumerate(parts[:-1]):
            child = node.setdefault(part, {})
            if not isinstance(child, dict):
                # a dotted key can only descend into tables; 'seed.x' would assign into the int seed
                table = ".".join(parts[: i + 1])
                raise IrlsimError(
                    f"config: cannot set '{key}': '{table}' is a value ({child!r}), not a table: "
                    f"set '{table}' itself (e.g. --set {table}=...) or check the key"
                )
            node = child
        node[parts[-1]] = value
    return data


def _build(cls: type[T], data: dict[str, Any], hook: bool = True, scenarios: Any = None) -> T:
    with_defaults = getattr(cls, "with_defaults", None)  # defaults that depend on the data (a scenario's)
    if hook and callable(with_defaults):
        data = with_defaults(data, scenarios)
    return from_dict(cls, data)


def _builds(cls: type[Any], data: dict[str, Any], hook: bool) -> bool:
    try:
        _build(cls, data, hook)
    except IrlsimError:
        return False
    return True


def _blame(
    cls: type[Any],
    data: dict[str, Any],
    overrides: dict[str, Any],
    labels: dict[str, str],
    path: str | Path | None,
    full: dict[str, Any],
) -> str | None:
    """Where the value that fails came from (None: unknown). Only on the error path: the config is built
    again without a source to see whether it was that one. The scenario's ``[defaults]``, when the config
    builds without them; else the first override (in the order given) whose addition to the file makes
    it fail; else the file."""
    source = getattr(cls, "defaults_source", None)
    if callable(source) and _builds(cls, full, hook=False):
        return source(full)  # type: ignore[no-any-return]
    if overrides and _builds(cls, data, hook=False):
        given: dict[str, Any] = {}
        for key, value in overrides.items():
            given[key] = value
            if not _builds(cls, _with_overrides(data, given), hook=False):
                return labels.get(key, f"--set {key}")
    return f"config file {path}" if path is not None else None


def require(cond: bool, message: str) -> None:
    """Raise an IrlsimError with ``message`` unless ``cond`` holds (config validation helper)."""
    if not cond:
        raise IrlsimError(f"config: {message}")


def parse_overrides(items: list[str] | None) -> dict[str, Any]:
    """``["epochs=3", "model.latent=16", "models=['LIRL']"]`` -> dotted-key overrides (TOML values).

    A value that is not valid TOML is taken as a string, so ``name=foo`` works without quotes.
    """
    out: dict[str, Any] = {}
    for item in items or []:
        key, sep, raw = item.partition("=")
        if not sep or not key.strip():
            raise IrlsimError(f"--set '{item}' must look like key=value (e.g. --set epochs=5)")
        try:
            value = tomllib.loads(f"v = {raw}")["v"]
        except tomllib.TOMLDecodeError:
            value = raw
        out[key.strip()] = value
    return out


#: the largest seed irlsim passes on (SUMO's --seed and torch take a signed 32-bit int)
MAX_SEED = 2**31 - 1


def int_in(lo: int, hi: int | None = None) -> Any:
    """An argparse ``type=``: an integer in ``lo..hi`` (no upper bound when ``hi`` is None), else the
    parser's one-line error (exit 2) before any work."""

    def parse(text: str) -> int:
        try:
            value = int(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"must be an integer, got {text!r}") from None
        if value < lo or (hi is not None and value > hi):
            bound = f"{lo}..{hi}" if hi is not None else f">= {lo}"
            raise argparse.ArgumentTypeError(f"must be an integer {bound}, got {value}")
        return value

    parse.__name__ = "integer"
    return parse


def float_in(lo: float, hi: float | None = None, *, above: bool = False) -> Any:
    """An argparse ``type=``: a finite number in ``[lo, hi]`` (``above``: in ``(lo, hi]``, e.g. a time
    limit > 0), else the parser's one-line error."""

    def parse(text: str) -> float:
        try:
            value = float(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"must be a number, got {text!r}") from None
        low = value <= lo if above else value < lo
        if not math.isfinite(value) or low or (hi is not None and value > hi):
            start = f"({lo:g}" if above else f"[{lo:g}"
            bound = f"in {start}, {hi:g}]" if hi is not None else f"{'>' if above else '>='} {lo:g}"
            raise argparse.ArgumentTypeError(f"must be a finite number {bound}, got {text}")
        return value

    parse.__name__ = "number"
    return parse


def available_memory() -> int:
    """Bytes of memory this process may still allocate: MemAvailable of /proc/meminfo (Linux), else the
    physical memory."""
    try:
        with open("/proc/meminfo") as f:
            for line in f:
                if line.startswith("MemAvailable:"):
                    return int(line.split()[1]) * 1024
    except (OSError, ValueError, IndexError):
        pass
    try:
        return int(os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES"))
    except (OSError, ValueError, AttributeError):  # pragma: no cover - not POSIX
        return 2**62


def require_memory(what: str, needed: int, fix: str) -> None:
    """Refuse (one line, before allocation) a size whose estimated memory ``needed`` [bytes] exceeds what
    is available."""
    have = available_memory()
    if needed > have:
        raise IrlsimError(
            f"config: {what} needs about {needed / 2**30:.1f} GiB of memory, {have / 2**30:.1f} GiB are "
            f"available: {fix}"
        )

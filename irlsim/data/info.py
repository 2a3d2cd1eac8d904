"""A dataset summary for ``irlsim info``: counts, feature statistics, demonstration quality, disk size.

Everything is computed row group by row group, so memory stays bounded at any dataset size.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import numpy as np

from irlsim.data.aggregate import AggregateDataset, open_datasets
from irlsim.data.by_demonstrator import dataset_demonstrator
from irlsim.data.cache import CACHE_DIR
from irlsim.data.demonstrator import describe
from irlsim.data.reader import fixed_list_to_numpy, iter_policy_groups, open_dataset, open_parquet
from irlsim.data.roads import episode_scenario, records_scenarios
from irlsim.data.schema import TABLE_POLICIES, stats_name
from irlsim.rollout.style import format_style, pool_styles


class _Moments:
    """Running count, sum, sum of squares, min and max per column (float64)."""

    def __init__(self, width: int) -> None:
        self.n = 0
        self.sum = np.zeros(width)
        self.sumsq = np.zeros(width)
        self.min = np.full(width, np.inf)
        self.max = np.full(width, -np.inf)

    def add(self, x: np.ndarray) -> None:  # x: [rows, width]
        if not len(x):
            return
        x = x.astype(np.float64)
        self.n += len(x)
        self.sum += x.sum(axis=0)
        self.sumsq += np.square(x).sum(axis=0)
        self.min = np.minimum(self.min, x.min(axis=0))
        self.max = np.maximum(self.max, x.max(axis=0))

    def summary(self) -> dict[str, np.ndarray]:
        n = max(self.n, 1)
        mean = self.sum / n
        std = np.sqrt(np.maximum(self.sumsq / n - mean**2, 0.0))
        nan = np.full_like(mean, np.nan)
        if self.n == 0:
            return {"mean": nan, "std": nan, "min": nan, "max": nan}
        return {"mean": mean, "std": std, "min": self.min, "max": self.max}


def _dir_size(path: Path, *, skip: str | None = None) -> int:
    total = 0
    for p in path.rglob("*"):
        if skip and skip in p.relative_to(path).parts:
            continue
        if p.is_file():
            total += p.stat().st_size
    return total


def dataset_info(path: str | Path) -> dict[str, Any]:
    """Summary of a dataset as a JSON-ready dict.

    Keys: ``path``, ``schema_version``, ``splits`` {split: {episodes, cycles, cycles_with_demo,
    policies_per_cycle, demo_distance {mean, median, p90} [m], random_policy_distance [m]}},
    ``features`` {name: {mean, std, min, max}} over all policies of all splits, ``disk_bytes`` (Parquet
    and manifest) and ``cache_bytes``; ``scenarios`` {name: {split: episodes}} where the manifest records
    its roads; ``demonstrator`` (who drove: 'expert', or SUMO's models and attributes) and ``style`` (the
    driving style of the demonstrations, :func:`irlsim.rollout.style.pool_styles` over the episodes whose
    figures recorded it). ``random_policy_distance`` is the mean d(zeta, pi) over all policies
    of the cycles with a demonstration, i.e. the expected distance of a uniformly random policy, to compare
    with the DEMO mean.
    """
    ds = open_dataset(path)
    names = list(ds.manifest["feature_names"])
    moments = _Moments(len(names))
    splits: dict[str, Any] = {}
    for split in ds.splits:
        cycles = ds.read_cycles_table(split)
        has_demo = cycles.column("has_demo").to_numpy(zero_copy_only=False)
        demo_d = cycles.column("demo_distance").to_numpy()[has_demo].astype(np.float64)
        n_pol = cycles.column("n_policies").to_numpy()
        rand_sum, rand_n, offset = 0.0, 0, 0  # offset: first cycles row of the current row group
        for ep in ds.episodes(split):
            p = ds.policies_path(split, ep)
            pf = open_parquet(p, TABLE_POLICIES, n_features=len(names))
            for group in iter_policy_groups(pf, p, ["features", "distance"]):
                moments.add(fixed_list_to_numpy(group.column("features"), len(names)))
                n = int(n_pol[0])
                g = group.num_rows // n
                dist = group.column("distance").to_numpy().reshape(g, n)[has_demo[offset : offset + g]]
                rand_sum += float(dist.astype(np.float64).sum())
                rand_n += dist.size
                offset += g
        splits[split] = {
            "episodes": len(ds.episodes(split)),
            "cycles": cycles.num_rows,
            "cycles_with_demo": int(has_demo.sum()),
            "policies_per_cycle": int(n_pol[0]) if n_pol.size else 0,
            "demo_distance": {
                "mean": float(demo_d.mean()) if demo_d.size else float("nan"),
                "median": float(np.median(demo_d)) if demo_d.size else float("nan"),
                "p90": float(np.percentile(demo_d, 90)) if demo_d.size else float("nan"),
            },
            "random_policy_distance": rand_sum / rand_n if rand_n else float("nan"),
        }
    stats = moments.summary()
    roads: dict[str, Any] = {}
    if records_scenarios(ds.manifest):  # a dataset over several scenarios, or one other than the oval
        roads["scenarios"] = {
            name: {
                s: sum(episode_scenario(ds.manifest, s, e) == name for e in ds.episodes(s)) for s in ds.splits
            }
            for name in ds.scenarios
        }
    return {
        "path": str(ds.path),
        "schema_version": ds.manifest["schema_version"],
        "splits": splits,
        "features": {
            name: {key: float(stats[key][i]) for key in ("mean", "std", "min", "max")}
            for i, name in enumerate(names)
        },
        "disk_bytes": _dir_size(ds.path, skip=CACHE_DIR),
        "cache_bytes": _dir_size(ds.path / CACHE_DIR) if (ds.path / CACHE_DIR).is_dir() else 0,
        **roads,
        "demonstrator": describe(ds.manifest.get("demonstrator")),
        "style": pool_styles(_episode_styles(ds)),
        "demonstrators": demonstrator_breakdown([ds]),
    }


def demonstrator_breakdown(parts: list[Any]) -> dict[str, Any]:
    """{identity: {'name', 'episodes' {split: n}, 'cycles', 'style'}} of the folders ``parts`` (each the
    data of one demonstrator, :mod:`irlsim.data.by_demonstrator`), in folder order; a demonstrator of
    several folders pools them."""
    out: dict[str, Any] = {}
    styles: dict[str, list[dict[str, Any]]] = {}
    for d in parts:
        ident = dataset_demonstrator(d)
        entry = out.setdefault(
            ident, {"name": describe(d.manifest.get("demonstrator")), "episodes": {}, "cycles": 0}
        )
        for split in d.splits:
            entry["episodes"][split] = entry["episodes"].get(split, 0) + len(d.episodes(split))
            entry["cycles"] += int(d.read_cycles_table(split).num_rows)
        styles.setdefault(ident, []).extend(_episode_styles(d))
    for ident, entry in out.items():
        entry["style"] = pool_styles(styles[ident])
    return out


def aggregate_info(paths: list[Path]) -> dict[str, Any]:
    """The summary of folders read as one (``irlsim data info A B``): each folder's path and demonstrator
    and the breakdown per demonstrator (:func:`demonstrator_breakdown`); refused in one line as
    ``irlsim train --data A B`` refuses them (a folder twice, another planner)."""
    agg = open_datasets(list(paths))
    parts = agg.datasets if isinstance(agg, AggregateDataset) else [agg]
    return {
        "paths": [str(d.path) for d in parts],
        "folders": [dataset_demonstrator(d) for d in parts],
        "demonstrators": demonstrator_breakdown(parts),
    }


def format_demonstrators(info: dict[str, Any]) -> str:
    """The breakdown per demonstrator as text: identity, name, episodes per split, cycles, style."""
    lines = []
    for ident, e in info["demonstrators"].items():
        eps = ", ".join(f"{s} {n}" for s, n in e["episodes"].items())
        lines.append(f"{ident} ({e['name']}): episodes {eps}; {e['cycles']} cycles")
        lines.append(format_style(e["style"] or {}))
    return "\n".join(lines)


def format_aggregate(info: dict[str, Any]) -> str:
    """``aggregate_info`` as a plain-text report."""
    lines = ["datasets read as one (in folder order):"]
    lines += [f"  {p}: {who}" for p, who in zip(info["paths"], info["folders"], strict=True)]
    lines += ["", "per demonstrator:", format_demonstrators(info)]
    return "\n".join(lines)


def _episode_styles(ds: Any) -> list[dict[str, Any]]:
    """Every episode's style figures from its ``.stats.json`` (episodes without them are left out)."""
    out = []
    for split in ds.splits:
        for ep in ds.episodes(split):
            p = ds.path / split / stats_name(ep)
            try:
                stats = json.loads(p.read_text())
            except (OSError, ValueError):  # informational figures: missing or unreadable ones are skipped
                continue
            if isinstance(stats, dict) and "style/time_s" in stats:
                out.append(stats)
    return out


def _mb(n: int) -> str:
    return f"{n / 2**20:.1f} MiB"


def format_info(info: dict[str, Any]) -> str:
    """``dataset_info`` as an aligned plain-text report."""
    lines = [f"dataset {info['path']} (schema version {info['schema_version']})", ""]
    lines.append(
        f"{'split':<12}{'episodes':>9}{'cycles':>9}{'w/ demo':>9}{'policies':>9}"
        f"{'DEMO mean':>11}{'median':>9}{'p90':>8}{'random':>9}"
    )
    for name, s in info["splits"].items():
        d = s["demo_distance"]
        lines.append(
            f"{name:<12}{s['episodes']:>9}{s['cycles']:>9}{s['cycles_with_demo']:>9}{s['policies_per_cycle']:>9}"
            f"{d['mean']:>11.3f}{d['median']:>9.3f}{d['p90']:>8.3f}{s['random_policy_distance']:>9.3f}"
        )
    if "scenarios" in info:
        per = [
            f"{k} ({', '.join(f'{s} {n}' for s, n in eps.items())})" for k, eps in info["scenarios"].items()
        ]
        lines += ["", "scenarios (episodes): " + "; ".join(per)]
    if "demonstrator" in info:
        lines += ["", f"demonstrator: {info['demonstrator']}", format_style(info.get("style") or {})]
    if "demonstrators" in info:
        lines += ["", "per demonstrator:", format_demonstrators(info)]
    lines += [
        "",
        "distances in m; random = mean distance of a uniformly random policy (cycles with a demo)",
        "",
    ]
    lines.append(f"{'feature':<16}{'mean':>12}{'std':>12}{'min':>12}{'max':>12}")
    for name, f in info["features"].items():
        lines.append(f"{name:<16}{f['mean']:>12.4g}{f['std']:>12.4g}{f['min']:>12.4g}{f['max']:>12.4g}")
    lines += ["", f"disk: {_mb(info['disk_bytes'])} (cache {_mb(info['cache_bytes'])})"]
    return "\n".join(lines)

"""Evaluation: Table I of the paper (model, trainable parameters, EVD, ED, OPD, DEMO) and plots.

Protocol (docs/design/demonstrations.md): on the sequential test split every model may use cycles <= t for
cycle t; stage-1 models use the mean of their last H predicted thetas within the episode, PTACNN(+S) its
temporal mixture over the H-cycle history ending at t. PTACNN's H is fixed by its weights (one softmax
weight per history entry), so every row uses that H; asking for another is refused. Metrics are
averaged over cycles that have a demonstration. References: each model's OPD at its initial weights
(column 'OPD untrained', same sizes and normalisation, seed 0) and a 'random policy' row (a uniformly
random policy per cycle; ED is the mean distance over the policy set, OPD the distance of the random
pick, no EVD).

Reference rows (irlsim.irl.references): 'expert-theta' (the hand-tuned theta, argmax V),
'executed' (the policy the demonstrator executed), 'oracle' (a per-cycle linear theta fitted to that
cycle's own demonstration: an optimistic bound, not a model). On a dataset read from disk every row also
gets OPD / ED per situation label and its reward stability (irlsim.irl.breakdown).
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
import torch

from irlsim import N_FEATURES, feature_names_of
from irlsim.data.roads import records_scenarios
from irlsim.data.situations import SITUATION_NAMES
from irlsim.devices import current_device
from irlsim.errors import IrlsimError
from irlsim.irl.breakdown import CycleContext, breakdown_markdown, row_breakdown
from irlsim.irl.objectives import evaluate_thetas, history_mean, summarize
from irlsim.irl.references import executed_metrics, expert_theta_metrics, oracle_metrics
from irlsim.irl.stability import temporal_weight_summary
from irlsim.models.normalization import FeatureStats
from irlsim.models.registry import MODEL_NAMES, build_model, format_parameters
from irlsim.planner.expert import expert_theta
from irlsim.train.batching import as_dataset, check_split_shape, get_split, predict_split
from irlsim.train.checkpoint import model_config_from
from irlsim.train.layout import STAGE_FOLDERS, find_checkpoint
from irlsim.train.loading import LoadedModel, load_model
from irlsim.train.repro import num_threads, provenance
from irlsim.train.stage2 import predict_temporal
from irlsim.utils import atomic_path, atomic_write_text, owned_output, write_json

METRIC_KEYS = ("evd", "ed", "opd", "demo")
#: the reference rows after the trained models, in this order (irlsim.irl.references)
REFERENCE_ROWS = ("expert-theta", "executed", "oracle (optimistic bound)", "random policy")
#: H [cycles] when no --history is given and no temporal model fixes it (the paper's H)
DEFAULT_HISTORY = 10


def resolve_history(loaded: dict[str, LoadedModel], H: int | None) -> int:
    """The history H every row uses: ``H`` if given, else the temporal models' own H, else
    DEFAULT_HISTORY. A temporal model trained with another H than the one asked for is refused."""
    temporal = {name: lm.history for name, lm in loaded.items() if lm.history is not None}
    if H is None:
        if len(set(temporal.values())) > 1:
            found = ", ".join(f"{n} H={h}" for n, h in temporal.items())
            raise IrlsimError(
                f"the temporal models were trained with different histories ({found}): evaluate them in "
                "separate runs folders"
            )
        return next(iter(temporal.values()), DEFAULT_HISTORY)
    if H < 1:
        raise IrlsimError(f"--history must be >= 1, got {H}")
    for name, h in temporal.items():
        if h != H:
            raise IrlsimError(
                f"{name} was trained with a history of H={h} cycles and cannot use --history {H} (it weighs "
                f"exactly H past cycles): pass --history {h} (or omit it), or retrain stage 2 with "
                f"--set model.history={H}"
            )
    return H


def predict_sequential(loaded: LoadedModel, split: Any, H: int = 10, chunk: int = 64) -> np.ndarray:
    """Thetas [C, 15] a model uses on a sequential split (history mean or temporal mixture)."""
    return predict_sequential_weights(loaded, split, H, chunk)[0]


def predict_sequential_weights(
    loaded: LoadedModel, split: Any, H: int = 10, chunk: int = 64
) -> tuple[np.ndarray, np.ndarray | None]:
    """(thetas [C, 15], temporal weights [C, H] or None for a stage-1 model) on a sequential split."""
    episode = np.asarray(split.episode)
    if loaded.history is not None and loaded.history != H:
        resolve_history({loaded.name: loaded}, H)  # raises the one-line refusal
    if loaded.base is None:
        return history_mean(
            predict_split(loaded.model, split, chunk, keep=("theta",))["theta"], episode, H
        ), None
    base = predict_split(loaded.base, split, chunk, keep=("theta", "context"))
    return predict_temporal(loaded.model, base["context"], base["theta"], episode)


def random_policy_metrics(split: Any, seed: int = 0, chunk: int = 256) -> dict[str, np.ndarray]:
    """Per-cycle metrics of picking a uniformly random policy: ED = mean distance, OPD = random pick."""
    rng = np.random.default_rng(seed)
    c, n = split.distances.shape
    ed, opd = np.zeros(c), np.zeros(c)
    for start in range(0, c, chunk):
        d = np.asarray(split.distances[start : start + chunk], dtype=np.float64)
        ed[start : start + len(d)] = d.mean(1)
        opd[start : start + len(d)] = d[np.arange(len(d)), rng.integers(0, n, len(d))]
    demo_index = np.asarray(split.demo_index)
    valid = demo_index >= 0
    demo = np.full(c, np.nan)
    rows = np.flatnonzero(valid)
    for start in range(0, len(rows), chunk):
        r = rows[start : start + chunk]
        demo[r] = np.asarray(split.distances[r])[np.arange(len(r)), demo_index[r]]
    return {"evd": np.full(c, np.nan), "ed": ed, "opd": opd, "demo": demo, "valid": valid}


def untrained_like(lm: LoadedModel, seed: int = 0) -> LoadedModel:
    """The same architecture, sizes and feature normalisation as ``lm`` at its initial weights.

    For PTACNN(+S) both the temporal network and its PACNN base are fresh: every parameter the model
    learned (in stage 1 or 2) is back at initialisation. The reference for "learning is real".
    """
    entry = lm.checkpoint["base"] if lm.base is not None else lm.checkpoint
    stats = FeatureStats.from_dict(entry["feature_stats"])
    torch.manual_seed(seed)
    stage1 = build_model(
        entry["model"], model_config_from(entry["model_config"]), int(entry["n_policies"]), stats
    )
    if lm.base is None:
        return LoadedModel(lm.name, stage1.to(current_device()).eval(), None, None, lm.checkpoint)
    cfg = model_config_from(lm.checkpoint["model_config"])
    temporal = build_model(lm.name, cfg, 1, stats)
    dev = current_device()
    return LoadedModel(lm.name, temporal.to(dev).eval(), stage1.to(dev).eval(), cfg.history, lm.checkpoint)


def _row(model: str, params: str, n_params: list[int], metrics: dict[str, np.ndarray]) -> dict[str, Any]:
    s = summarize(metrics)
    return {
        "model": model,
        "parameters": params,
        "parameter_counts": n_params,
        **{k: s[k] for k in METRIC_KEYS},
        "cycles": int(metrics["valid"].sum()),
    }


def _fmt(v: float) -> str:
    return "–" if v is None or (isinstance(v, float) and math.isnan(v)) else f"{v:.3f}"


def results_markdown(
    rows: list[dict[str, Any]], split_name: str, H: int, n_features: int = N_FEATURES
) -> str:
    """Table I as markdown; ``n_features``: the dataset's feature set's size (the oracle's note)."""
    lines = [
        f"# Results on the {split_name} split (history H = {H} cycles)",
        "",
        "| model | trainable parameters | EVD | ED [m] | OPD [m] | DEMO [m] | OPD untrained [m] | epoch |",
        "|---|---|---|---|---|---|---|---|",
    ]
    for r in rows:
        lines.append(
            f"| {r['model']} | {r['parameters']} | "
            + " | ".join(_fmt(r[k]) for k in METRIC_KEYS)
            + f" | {_fmt(r.get('opd_untrained', float('nan')))} | {r.get('selected_epoch', '–')} |"
        )
    lines += [
        "",
        "EVD: expected value difference (relative); ED: expected distance of p(pi|theta) to the "
        "demonstration; OPD: distance of the optimal policy; DEMO: distance of the demonstration "
        "(lower bound of OPD); OPD untrained: the same model at its initial weights; epoch: the "
        "validation-selected epoch whose weights were evaluated (select_by in the train config). Means "
        "over cycles with a demonstration. Reference rows: expert-theta = the expert's hand-tuned theta, "
        "argmax V; executed = the policy the demonstrator executed (a choice: ED = OPD); oracle = a "
        "per-cycle linear theta fitted to that cycle's own demonstration, an OPTIMISTIC BOUND on any "
        f"linear reward over the {n_features} features (it sees the answer), not a model.",
        "",
    ]
    lines.append(breakdown_markdown(rows))
    trained = sorted({_provenance_text(r["provenance"]) for r in rows if r.get("provenance")})
    if trained:  # the weights' bytes depend on these (irlsim.train.repro.provenance)
        lines += [f"Trained with {'; '.join(trained)}.", ""]
    return "\n".join(lines)


def _provenance_text(p: dict[str, Any]) -> str:
    threads = f"{p['threads']} thread" + ("s" if p["threads"] != 1 else "")
    return f"torch {p['torch']}, {threads}, {p['cpu_capability']} kernels"


def _savefig(fig: Any, path: Path) -> None:
    with atomic_path(path) as tmp:
        fig.savefig(tmp, format="png", dpi=120, bbox_inches="tight")


def plot_convergence(metrics: dict[str, list[dict[str, Any]]], path: Path) -> None:
    """Train EVD per epoch and validation ED per validation epoch, one line per model (``metrics``: model
    -> its checkpoint's per-epoch rows, the values of its metrics.csv without the wall times, read from
    the checkpoint whose records' CRC-32 were checked rather than from the csv, which carries none)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, (ax1, ax2) = plt.subplots(1, 2, figsize=(10, 4))
    for m, rows in metrics.items():
        if not rows:
            continue
        ep = np.array([_number(r.get("epoch")) for r in rows])
        evd = np.array([_number(r.get("train/evd")) for r in rows])
        ed = np.array([_number(r.get("val/ed")) for r in rows])
        ax1.plot(ep, evd, label=m)
        ok = np.isfinite(ed)
        ax2.plot(ep[ok], ed[ok], marker="o", label=m)
    ax1.set(title="training: EVD on train", xlabel="epoch", ylabel="EVD")
    ax2.set(title="validation: ED on validation", xlabel="epoch", ylabel="ED [m]")
    for ax in (ax1, ax2):
        ax.grid(alpha=0.3)
        ax.legend(fontsize=8)
    _savefig(fig, path)
    plt.close(fig)


def _number(v: Any) -> float:
    """A metric value as a float (None, a missing value: NaN)."""
    return float("nan") if v is None else float(v)


def plot_opd(per_model: dict[str, np.ndarray], demo: np.ndarray, path: Path) -> None:
    """Distribution of OPD per model with DEMO (the lower bound) [m]."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(6, 4))
    finite = [v[np.isfinite(v)] for v in [*per_model.values(), demo]]
    hi = max([float(np.quantile(v, 0.99)) for v in finite if len(v)] + [1e-3])
    bins = np.linspace(0.0, hi, 40)
    for name, v in per_model.items():
        ax.hist(v[np.isfinite(v)], bins=bins.tolist(), histtype="step", density=True, label=name)
    ax.hist(
        demo[np.isfinite(demo)],
        bins=bins.tolist(),
        histtype="stepfilled",
        alpha=0.3,
        color="k",
        density=True,
        label="DEMO (lower bound)",
    )
    ax.set(
        title="test: distance of the optimal policy to the demonstration", xlabel="OPD [m]", ylabel="density"
    )
    ax.legend(fontsize=8)
    _savefig(fig, path)
    plt.close(fig)


def cycle_context(dataset: Any, split: str, data: Any) -> CycleContext | None:
    """Situations, ego (s, d) and time of the split's cycles; None for an in-memory dataset."""
    if not hasattr(dataset, "read_cycles"):
        return None
    horizon = float(((dataset.manifest.get("config") or {}).get("planner") or {}).get("horizon", 5.0))
    ctx = CycleContext.from_cycles(dataset.read_cycles(split), data, horizon, SITUATION_NAMES)
    # a dataset that records its roads (several scenarios, or one other than the oval): a breakdown by
    # scenario beside the one by situation (an oval dataset's results keep their bytes)
    parts = getattr(dataset, "datasets", [dataset])
    if any(records_scenarios(d.manifest) for d in parts):
        scenario = np.asarray(dataset.scenario_of_cycle(split))[: data.features.shape[0]]
        ctx = dataclasses.replace(ctx, scenario=scenario)
    # data of several demonstrators (an aggregate of their folders): a breakdown by demonstrator
    if hasattr(dataset, "demonstrator_of_cycle"):
        who = np.asarray(dataset.demonstrator_of_cycle(split))[: data.features.shape[0]]
        if len(set(who.tolist())) > 1:
            ctx = dataclasses.replace(ctx, demonstrator=who)
    return ctx


def reference_rows(data: Any, ctx: CycleContext | None, full: bool = True) -> list[dict[str, Any]]:
    """Table-I rows 'expert-theta', 'executed', 'oracle', 'random policy' (with breakdowns if ``ctx``);
    only 'random policy' if not ``full``."""
    refs: list[tuple[str, dict[str, np.ndarray], dict[str, Any]]] = []
    nf = data.features.shape[-1]
    if full:
        oracle, oracle_thetas = oracle_metrics(data)
        refs += [
            (
                "expert-theta",
                expert_theta_metrics(data),
                {"thetas": np.tile(expert_theta(feature_names_of(nf)), (data.features.shape[0], 1))},
            ),
            ("executed", executed_metrics(data), {"chosen": np.asarray(data.executed_index)}),
            ("oracle (optimistic bound)", oracle, {"thetas": oracle_thetas}),
        ]
    refs.append(("random policy", random_policy_metrics(data), {}))
    rows = []
    for name, metrics, extra in refs:
        row = _row(name, f"{nf} per cycle" if name.startswith("oracle") else "0", [0], metrics)
        if ctx is not None:
            row.update(row_breakdown(metrics, data, ctx, **extra))
            if name.startswith("oracle"):  # each cycle's fit has its own scale: a relative change is noise
                row["stability"].update(theta_change=float("nan"), theta_change_switch=float("nan"))
        rows.append(row)
    return rows


def temporal_outputs(
    name: str,
    weights: np.ndarray,
    data: Any,
    ctx: CycleContext | None,
    strips: Callable[..., dict[str, str]] | None = None,
) -> dict[str, Any]:
    """A temporal model's weight summary (irlsim.irl.stability.temporal_weight_summary), plus what
    ``strips(name, weights [C, H], situation [C], t [C], episode [C])`` returns (the pipeline draws the
    strips with irlsim.viz.temporal; train does not import viz)."""
    episode = np.asarray(data.episode)
    sit = ctx.situation if ctx is not None and (ctx.situation >= 0).all() else None
    out: dict[str, Any] = temporal_weight_summary(weights, sit, episode)
    if sit is not None and ctx is not None and strips is not None:
        out.update(strips(name, weights, sit, ctx.t, episode))
    return out


def _write_results(
    out_dir: Path, rows: list[dict[str, Any]], split: str, H: int, record: dict[str, Any], n_features: int
) -> None:
    """results.md (its last paragraph: the record's ``note``, if any) and results.json (the record)."""
    note = record.get("note")
    out_dir.mkdir(parents=True, exist_ok=True)
    atomic_write_text(
        out_dir / "results.md", results_markdown(rows, split, H, n_features) + (f"\n{note}\n" if note else "")
    )
    write_json(out_dir / "results.json", {"split": split, "history": H, **record, "rows": rows})


def evaluate_models(
    dataset: Any,
    runs_dir: str | Path,
    out_dir: str | Path,
    H: int | None = None,
    split: str = "test",
    threads: int = 2,
    references: bool = True,
    strips: Callable[..., dict[str, str]] | None = None,
    record: dict[str, Any] | None = None,
) -> list[dict[str, Any]]:
    """Evaluate every trained model in ``runs_dir`` on ``split``.

    Checkpoints are found by :func:`irlsim.train.layout.find_checkpoint` (``<runs>/stage1/<model>/``,
    ``<runs>/stage2/<model>/``, or ``<runs>/<model>/``). ``H``: the history [cycles]; None = the temporal
    models' own H (else 10); a temporal model trained with another H is refused. Writes
    ``out_dir/results.md``, ``results.json`` (with the H used and this process's provenance),
    ``convergence.png`` and ``opd_distribution.png`` (all atomically); returns the Table-I rows (model,
    parameters, parameter_counts, evd, ed, opd, demo, cycles, opd_untrained, selected_epoch,
    provenance, and on a dataset on disk 'situations' and 'stability'), trained models in registry order,
    then the reference rows 'expert-theta', 'executed', 'oracle (optimistic bound)' (unless not
    ``references``) and 'random policy'. ``strips``: see :func:`temporal_outputs`. ``record``: what the
    evaluation was (its data, whether held out, what the models were trained on) for results.json; its
    ``note`` is also the last line of results.md. An empty split is one line naming it.
    """
    dataset = as_dataset(dataset)
    runs_dir, out_dir = Path(runs_dir), Path(out_dir)
    found = {m: p for m in MODEL_NAMES if (p := find_checkpoint(runs_dir, m)) is not None}
    if not found:
        raise IrlsimError(
            f"no trained model in {runs_dir} (looked for {'/, '.join(STAGE_FOLDERS.values())}/<model>/"
            f"checkpoint.pt): train first with 'irlsim train --stage 1 --out {runs_dir}'"
        )
    data = get_split(dataset, split)
    if len(data.demo_index) == 0:
        raise IrlsimError(
            f"the {split} split of {getattr(dataset, 'path', 'the dataset')} is empty (no cycles): collect "
            f"it with {split}_episodes > 0, or evaluate another split (--split)"
        )
    loaded = {name: load_model(path, dataset) for name, path in found.items()}
    for name, lm in loaded.items():
        check_split_shape(name, lm.checkpoint["base"] if lm.base is not None else lm.checkpoint, data, split)
    H = resolve_history(loaded, H)
    ctx = cycle_context(dataset, split, data)
    with owned_output(out_dir, "evaluate"):  # one command writes an --out at a time
        with num_threads(threads):
            rows, opd = [], {}
            for name, lm in loaded.items():
                thetas, weights = predict_sequential_weights(lm, data, H)
                metrics = evaluate_thetas(thetas, data)
                a, b = lm.parameters
                params = (
                    format_parameters(a)
                    if lm.base is None
                    else f"{format_parameters(a)} + {format_parameters(b)}"
                )
                row = _row(name, params, [a] if lm.base is None else [a, b], metrics)
                untrained = evaluate_thetas(predict_sequential(untrained_like(lm), data, H), data)
                row["opd_untrained"] = summarize(untrained)["opd"]
                row["selected_epoch"] = (lm.checkpoint.get("best") or {}).get("epoch", lm.checkpoint["epoch"])
                # what the weights were trained with (older checkpoints: unknown)
                row["provenance"] = lm.checkpoint.get("provenance")
                if ctx is not None:
                    row.update(row_breakdown(metrics, data, ctx, thetas=thetas))
                if weights is not None:
                    row["temporal"] = temporal_outputs(name, weights, data, ctx, strips)
                rows.append(row)
                opd[name] = np.where(metrics["valid"], metrics["opd"], np.nan)
            rows += reference_rows(data, ctx, references)
            evaluated_with = provenance()

        meta = {"provenance": evaluated_with, **(record or {})}
        _write_results(out_dir, rows, split, H, meta, n_features=data.features.shape[-1])
        plot_convergence(
            {m: lm.checkpoint.get("metrics") or [] for m, lm in loaded.items()}, out_dir / "convergence.png"
        )
        demo_index = np.asarray(data.demo_index)
        demo = np.where(demo_index >= 0, random_policy_metrics(data)["demo"], np.nan)
        plot_opd(opd, demo, out_dir / "opd_distribution.png")
        return rows

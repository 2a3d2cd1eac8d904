"""``irlsim bench --train-throughput``: stage-1 training cycles per second of training settings side by
side, on a real dataset, through the real training loop (irlsim.train.stage1). Measured, never asserted.

Each variant is a stage-1 config (the baseline, the fast config, or the baseline with a few fields
overridden: one lever at a time). Each repeat trains every variant once, in turn (interleaved, so that
a busy machine slows all of them alike), for two epochs of the first ``max_cycles`` train cycles into a
temporary folder: epoch 1 without validation gives the training rate (cycles with a demonstration per
second: batching, forward, the max-ent loss, backward, the optimizer step and the checkpoint), epoch 2
adds one validation pass, whose extra time is reported apart. Reported: median, min and max over the
repeats, and each variant's median over the baseline's.
"""

from __future__ import annotations

import statistics
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from irlsim import devices
from irlsim.config import load_config, parse_overrides
from irlsim.train.batching import as_dataset, get_split
from irlsim.train.config import Stage1Config
from irlsim.train.metrics_log import read_metrics
from irlsim.train.stage1 import train_one_stage1

#: a lever override that is no config field: the torch precision of the forward pass (irlsim.devices)
PRECISION_KEY = "precision"


@dataclass(frozen=True)
class ThroughputRun:
    """What ``--train-throughput`` times: the dataset, the baseline and fast configs, the levers (each
    ``key=value[,key=value]`` overrides of the baseline; the key 'precision' picks the forward pass's
    torch precision, fp32 or bf16), the model and the size of each timed run."""

    data: Path
    baseline: Path = Path("configs/train/stage1.toml")
    fast: Path | None = Path("configs/train/stage1_sampled.toml")
    levers: tuple[str, ...] = ()
    model: str = "PACNN+S"
    max_cycles: int = 1024
    repeats: int = 3
    threads: int = 0
    """torch threads of every variant (0: each config's own; a lever may set threads)"""


def variants(run: ThroughputRun) -> dict[str, tuple[Stage1Config, str]]:
    """{name: (config, precision)}: 'baseline', one per lever (named by its overrides), 'fast'."""
    common: dict[str, Any] = {"models": [run.model], "epochs": 2, "validate_every": 2, "tensorboard": False}
    common |= {"max_cycles": run.max_cycles} | ({"threads": run.threads} if run.threads else {})
    out = {"baseline": (load_config(Stage1Config, run.baseline, dict(common)), "fp32")}
    for lever in run.levers:
        sets = parse_overrides([s for s in lever.split(",") if s.strip()])
        precision = devices.check_precision_on(
            devices.resolve_device("cpu"), str(sets.pop(PRECISION_KEY, "fp32"))
        )
        out[lever] = (load_config(Stage1Config, run.baseline, {**common, **sets}), precision)
    if run.fast is not None:
        out["fast"] = (load_config(Stage1Config, run.fast, dict(common)), "fp32")
    return out


def time_variant(dataset: Any, cfg: Stage1Config, precision: str) -> dict[str, float]:
    """One 2-epoch run of ``cfg`` -> {'cycles_per_s': train cycles/s of epoch 1 (no validation),
    'validation_s': epoch 2's time beyond epoch 1's (one validation pass), 'val/opd' after epoch 2}."""
    with tempfile.TemporaryDirectory() as tmp, devices.use("cpu", precision):
        summary = train_one_stage1(cfg.models[0], dataset, cfg, Path(tmp))
        rows = read_metrics(Path(tmp) / cfg.models[0] / "metrics.csv")
    del summary
    cycles = _train_cycles(dataset, cfg)
    first, second = rows[0]["time/epoch_s"], rows[1]["time/epoch_s"]
    return {
        "cycles_per_s": cycles / first,
        "validation_s": max(second - first, 0.0),
        "val/opd": float(rows[1].get("val/opd", float("nan"))),
    }


def _train_cycles(dataset: Any, cfg: Stage1Config) -> int:
    split = get_split(dataset, "train", cfg.safe_demos, cfg.stop_demos)
    demo = split.demo_index[: cfg.max_cycles] if cfg.max_cycles else split.demo_index
    return int((demo >= 0).sum())


def bench_train_throughput(run: ThroughputRun) -> dict[str, Any]:
    """Time every variant ``run.repeats`` times, interleaved; -> the JSON of the section."""
    dataset = as_dataset(run.data)
    chosen = variants(run)
    samples: dict[str, list[dict[str, float]]] = {name: [] for name in chosen}
    for rep in range(run.repeats):
        for name, (cfg, precision) in chosen.items():
            t0 = time.perf_counter()
            samples[name].append(time_variant(dataset, cfg, precision))
            print(f"  repeat {rep + 1}/{run.repeats} {name}: {time.perf_counter() - t0:.1f} s", flush=True)
    base = statistics.median(s["cycles_per_s"] for s in samples["baseline"])
    table = []
    for name, got in samples.items():
        rates = [s["cycles_per_s"] for s in got]
        cfg, precision = chosen[name]
        table.append(
            {
                "variant": name,
                "batch_size": cfg.batch_size,
                "threads": cfg.threads,
                "precision": precision,
                "cycles_per_s": round(statistics.median(rates), 1),
                "cycles_per_s_min": round(min(rates), 1),
                "cycles_per_s_max": round(max(rates), 1),
                "speedup": round(statistics.median(rates) / base, 2),
                "validation_s": round(statistics.median(s["validation_s"] for s in got), 2),
                "val/opd": round(statistics.median(s["val/opd"] for s in got), 3),
            }
        )
    return {
        "data": str(run.data),
        "model": run.model,
        "max_cycles": run.max_cycles,
        "repeats": run.repeats,
        "threads": run.threads,
        "variants": table,
    }


def markdown_table(result: dict[str, Any]) -> str:
    """The section's table in Markdown (what ``irlsim bench --train-throughput`` prints)."""
    lines = (
        []
        if not result["variants"]
        else [
            f"stage-1 {result['model']} training, first {result['max_cycles']} "
            f"train cycles of {result['data']}, {result['repeats']} interleaved repeats",
            "",
            "| variant | batch | threads | precision | cycles/s median [min, max] | x baseline | "
            "validation pass s | val OPD after 2 epochs [m] |",
            "|---|---|---|---|---|---|---|---|",
        ]
    )
    for r in result["variants"]:
        lines.append(
            f"| {r['variant']} | {r['batch_size']} | {r['threads']} | {r['precision']} | {r['cycles_per_s']} "
            f"[{r['cycles_per_s_min']}, {r['cycles_per_s_max']}] | {r['speedup']} | {r['validation_s']} | "
            f"{r['val/opd']} |"
        )
    side = result.get("side_levers")
    if side:
        lines += [
            "",
            "| normaliser policies | loss ms / batch | mean NLL bias [nats] | relative |",
            "|---|---|---|---|",
        ]
        lines += [
            f"| {r['policies']} | {r['loss_ms_per_batch']} | {r['nll_bias_mean']} | {r['nll_bias_rel']} |"
            for r in side["normaliser"]
        ]
        s16 = side["sixteen_bit"]
        lines += [
            "",
            f"gather ms / batch: float32 memory map {s16['gather_fp32_mmap_ms']}, float16 in memory "
            f"{s16['gather_fp16_ram_ms']}; float16 round trip max relative error {s16['max_rel_error']}",
        ]
    return "\n".join(lines) + "\n"

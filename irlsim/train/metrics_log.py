"""The per-epoch metrics log of a training run: ``metrics.csv`` (and TensorBoard when installed)."""

from __future__ import annotations

import csv
import io
import sys
from pathlib import Path
from typing import Any

import numpy as np

from irlsim.errors import IrlsimError
from irlsim.train.layout import METRICS_NAME
from irlsim.utils import atomic_write_text


class MetricsLog:
    """Per-epoch metric rows -> ``metrics.csv`` (rewritten atomically each epoch) and TensorBoard.

    Keys are namespaced (``train/nll``, ``val/ed``); an epoch without validation leaves the ``val/``
    columns empty. TensorBoard is used only if ``torch.utils.tensorboard`` imports (tensorboard installed);
    otherwise it is skipped silently.
    """

    def __init__(self, out_dir: Path, rows: list[dict[str, Any]] | None, tensorboard: bool) -> None:
        self.path = out_dir / METRICS_NAME
        self.rows = [dict(r) for r in rows or []]
        if (
            self.rows
        ):  # checkpoints keep no wall times (they would differ between identical runs): reuse the log's
            times = {int(r["epoch"]): r for r in _old_times(self.path) if r.get("epoch") == r.get("epoch")}
            for r in self.rows:
                old = times.get(int(r["epoch"]), {})
                r.update({k: v for k, v in old.items() if k.startswith("time/")})
        self.writer = None
        if tensorboard:
            try:
                from torch.utils.tensorboard import SummaryWriter

                self.writer = SummaryWriter(str(out_dir / "tensorboard"))
            except Exception:  # tensorboard not installed (or broken): CSV only
                self.writer = None

    def add(self, row: dict[str, Any]) -> None:
        self.rows.append(row)
        keys: list[str] = []
        for r in self.rows:
            keys += [k for k in r if k not in keys]
        buf = io.StringIO()
        w = csv.DictWriter(buf, fieldnames=keys, lineterminator="\n")
        w.writeheader()
        for r in self.rows:
            w.writerow({k: ("" if v is None else v) for k, v in r.items()})
        atomic_write_text(self.path, buf.getvalue())
        if self.writer is not None:
            for k, v in row.items():
                if k != "epoch" and isinstance(v, (int, float)) and np.isfinite(v):
                    self.writer.add_scalar(k, v, int(row["epoch"]))
            self.writer.flush()

    def close(self) -> None:
        if self.writer is not None:
            self.writer.close()


def read_metrics(path: str | Path) -> list[dict[str, float]]:
    """metrics.csv -> rows of floats (empty cells -> NaN); missing file -> []. A file that is not such a
    table (not UTF-8, a cell that is no number: a flipped bit) is one line naming it (IrlsimError)."""
    path = Path(path)
    if not path.is_file():
        return []
    try:
        with path.open(encoding="utf-8") as f:
            return [
                {k: (float(v) if v not in ("", None) else float("nan")) for k, v in r.items()}
                for r in csv.DictReader(f)
            ]
    except (ValueError, TypeError, csv.Error) as exc:  # UnicodeDecodeError is a ValueError
        reason = str(exc).splitlines()[0] if str(exc) else type(exc).__name__
        raise IrlsimError(f"{path} is not a metrics table ({reason}): delete it") from None


def _old_times(path: Path) -> list[dict[str, float]]:
    """The rows of a resumed run's metrics.csv, for their wall times; one that cannot be read loses them
    (one line on stderr): the metrics themselves come from the checkpoint."""
    try:
        return read_metrics(path)
    except IrlsimError as exc:
        print(f"irlsim: {exc} (its wall times are not kept; the checkpoint's metrics are)", file=sys.stderr)
        return []

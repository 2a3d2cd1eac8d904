"""Online reward prediction of a trained network: one call per planning cycle (imports torch)."""

from __future__ import annotations

from collections import deque
from pathlib import Path
from typing import Any

import numpy as np
import torch

from irlsim.devices import forward, to_device, to_numpy
from irlsim.train.loading import LoadedModel, load_model


class RewardPredictor:
    """Predict theta for the current planning cycle from its policy set.

    Stage-1 models (LIRL, 1DCNN, Bi1DCNN, PACNN, PACNN+S): the theta of this cycle alone (no history mean:
    in closed loop the newest prediction reacts fastest; the H-cycle mean is only the open-loop
    evaluation protocol of the paper). PTACNN(+S): the frozen PACNN's (context, theta) of this cycle is
    appended to an online history of the last H cycles (padded by repeating the first cycle of the
    episode), and the returned theta is the temporal-attention mixture over it. Call :meth:`reset` at the
    start of every episode.

    ``predict(features [N, 15], control_points [N, K, 3], actions [N, K, 2])`` ->
    ``(theta [15] float64 raw units, info)`` with info['attention'] [N] (PACNN-based models) and
    info['temporal_weights'] [H] (PTACNN, oldest first).
    """

    def __init__(self, model: LoadedModel | str | Path, threads: int = 1) -> None:
        self.loaded = model if isinstance(model, LoadedModel) else load_model(model)
        self.name = self.loaded.name
        self.threads = threads
        self.history: int | None = self.loaded.history
        self._contexts: deque[np.ndarray] = deque(maxlen=self.history or 1)
        self._thetas: deque[np.ndarray] = deque(maxlen=self.history or 1)

    def reset(self) -> None:
        """Forget the online history (new episode)."""
        self._contexts.clear()
        self._thetas.clear()

    @torch.no_grad()
    def predict(
        self, policy_features: np.ndarray, control_points: np.ndarray, actions: np.ndarray
    ) -> tuple[np.ndarray, dict[str, Any]]:
        torch.set_num_threads(self.threads)
        stage1 = self.loaded.base if self.loaded.base is not None else self.loaded.model
        raw = forward(
            stage1,
            to_device(torch.as_tensor(np.asarray(policy_features, dtype=np.float32))[None]),
            to_device(torch.as_tensor(np.asarray(control_points, dtype=np.float32))[None]),
            to_device(torch.as_tensor(np.asarray(actions, dtype=np.float32))[None]),
        )
        out: dict[str, np.ndarray] = {k: to_numpy(v) for k, v in raw.items()}
        info: dict[str, Any] = {}
        if "attention" in out:
            info["attention"] = out["attention"][0]
        theta = out["theta"][0]
        if self.loaded.base is not None:
            assert self.history is not None
            if not self._thetas:  # first cycle of the episode: pad by repetition
                for _ in range(self.history - 1):
                    self._contexts.append(out["context"][0])
                    self._thetas.append(theta)
            self._contexts.append(out["context"][0])
            self._thetas.append(theta)
            raw_mix = forward(
                self.loaded.model,
                to_device(torch.as_tensor(np.stack(self._contexts))[None]),
                to_device(torch.as_tensor(np.stack(self._thetas))[None]),
            )
            mix = {k: to_numpy(v) for k, v in raw_mix.items()}
            theta = mix["theta"][0]
            info["temporal_weights"] = mix["weights"][0].astype(np.float64)
            info["stage1_theta"] = out["theta"][0].astype(np.float64)
        return theta.astype(np.float64), info

"""The learned reward of one trained model: :func:`load_reward` and :class:`LearnedReward`.

    from irlsim.reward import load_reward
    reward = load_reward("PACNN+S", runs="runs/tiny")   # or a checkpoint path, "LIRL", "expert-theta", ...
    reward.reset()                      # a new episode (PTACNN's history starts empty)
    theta = reward.theta(policy_set)    # [15]: one weight per feature, raw feature units
    values = reward.values(policy_set)  # [N]: V = -theta^T f of every policy (what the planner ranks)
    index = reward.choose(policy_set)   # argmax V: the policy the learned reward executes

One call per planning cycle: ``theta`` predicts once per policy set; ``values`` and ``choose`` on the same
set (the same object) reuse that prediction, so a temporal model's history advances once per cycle
whichever of the three is called first. A new episode starts with :meth:`LearnedReward.reset`.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any, Protocol

import numpy as np

from irlsim import FEATURE_NAMES, feature_names_of, feature_set_of
from irlsim.errors import IrlsimError
from irlsim.planner.expert import THETA_EXPERT, choose_index, expert_theta
from irlsim.planner.policy_set import PolicySet

EXPERT = "expert"
#: the expert's hand-tuned theta alone: argmax V every cycle, without the expert's model-based selection
#: (the best a single linear reward of these features is known to do; LIRL's reference)
EXPERT_THETA = "expert-theta"


class ThetaPredictor(Protocol):
    """What a learned reward predicts with: theta [15] (and pictures' info) from one cycle's policy set;
    :class:`irlsim.reward.predictor.RewardPredictor` and :class:`FixedTheta` are ones."""

    name: str

    def predict(
        self, features: np.ndarray, control_points: np.ndarray, actions: np.ndarray
    ) -> tuple[np.ndarray, dict[str, Any]]: ...

    def reset(self) -> None: ...


def _names_of(features: np.ndarray | None) -> tuple[str, ...]:
    """The feature set of a cycle's features [N, F] (None: the paper's)."""
    return FEATURE_NAMES if features is None else feature_names_of(np.shape(features)[-1])


class FixedTheta:
    """A reward 'predictor' that always returns the expert's theta (``expert-theta``)."""

    name = EXPERT_THETA

    def predict(
        self, features: np.ndarray, control_points: np.ndarray, actions: np.ndarray
    ) -> tuple[np.ndarray, dict[str, Any]]:
        return expert_theta(_names_of(features)), {}

    def reset(self) -> None:
        pass


class LearnedReward:
    """One reward model: ``name``, its ``checkpoint`` (None for 'expert' and 'expert-theta') and its
    ``predictor`` (None for 'expert', whose choice is a model-based rule: :attr:`is_expert`).

    ``theta(ps) -> [15]``, ``values(ps) -> [N]``, ``choose(ps, safety=False) -> int`` (see the module
    docstring), ``predict(features, control_points, actions) -> [15]`` for a cycle given as arrays;
    :attr:`info` holds the last prediction's extras (``attention`` [N] of PACNN-based models,
    ``temporal_weights`` [H] and ``stage1_theta`` [15] of PTACNN(+S)). 'expert' gives its theta and values
    but refuses ``choose``: its selection needs the planner that sampled the set
    (:class:`irlsim.planner.expert.ExpertDriver`).
    """

    def __init__(self, name: str, predictor: ThetaPredictor | None = None, checkpoint: Path | None = None):
        self.name = name
        self.predictor = predictor
        self.checkpoint = checkpoint
        self.info: dict[str, Any] = {}
        self._last_set: PolicySet | None = None
        self._last_theta: np.ndarray = THETA_EXPERT

    @property
    def is_expert(self) -> bool:
        return self.predictor is None

    @property
    def trained(self) -> dict[str, Any] | None:
        """The checkpoint's contents (its ``dataset``, ``dataset_seeds``, ...), None without one."""
        loaded = getattr(self.predictor, "loaded", None)
        return loaded.checkpoint if loaded is not None else None

    def reset(self) -> None:
        """A new episode: a temporal model's online history starts empty."""
        self._last_set = None
        self.info = {}
        if self.predictor is not None:
            self.predictor.reset()

    def theta(self, policy_set: PolicySet) -> np.ndarray:
        """theta [15] (float64, raw feature units) of this cycle's policy set; predicted once per set."""
        if policy_set is self._last_set:
            return self._last_theta
        theta = self.predict(policy_set.features, policy_set.control_points, policy_set.actions)
        self._last_set, self._last_theta = policy_set, theta
        return theta

    def predict(self, features: np.ndarray, control_points: np.ndarray, actions: np.ndarray) -> np.ndarray:
        """theta [15] of one cycle given as arrays (a stored cycle of a dataset, no PolicySet):
        ``features`` [N, 15], ``control_points`` [N, K, 3], ``actions`` [N, K, 2]. Every call is a new
        cycle (a temporal model's history advances); sets :attr:`info`."""
        self._last_set = None  # the history moved on: a set seen before is predicted anew
        info: dict[str, Any] = {}
        if self.predictor is None:
            theta = expert_theta(_names_of(features))
        else:
            theta, info = self.predictor.predict(features, control_points, actions)
        self.info = info
        return theta

    def values(self, policy_set: PolicySet) -> np.ndarray:
        """V = -theta^T f of every policy of the set: [N] float64 (higher is better)."""
        return policy_set.value(self.theta(policy_set))

    def choose(
        self,
        policy_set: PolicySet,
        safety: bool = False,
        choice: str = "argmax",
        lane_change_bias: float = 1.0,
        heading: int | None = None,
        stopping: bool = False,
        braking: np.ndarray | None = None,
        distance: np.ndarray | None = None,
        in_lane: bool = False,
    ) -> int:
        """The policy this reward executes: argmax V. ``safety``: first drop the policies labelled
        collision / off-road / exit (all kept when that drops every one), as ``irlsim drive --safety``;
        ``choice`` 'expected': the fit's expected maneuver and policy instead, 'maneuver': that maneuver's
        most likely policy (:mod:`irlsim.planner.choice`, ``irlsim drive --choice``); ``heading``,
        ``stopping``: a lane change under way to that lane, or a stop, is finished (``irlsim drive
        --commit``; see ``choose_index``); ``stopping`` and ``braking`` =
        ``irlsim.planner.expert.within_braking_curve(...)``: ``irlsim drive --full-stop``; ``distance`` =
        ``irlsim.planner.expert.keeping_distance(...)``: ``irlsim drive --keep-distance``; ``in_lane``: that
        distance kept in the lane the reward chooses (``irlsim drive --in-lane``)."""
        if self.is_expert:
            raise IrlsimError(
                "'expert' chooses by a model-based rule on its own planner's internals, not by a reward: "
                "drive it with irlsim.planner.expert.ExpertDriver, or load 'expert-theta' (its theta alone)"
            )
        return choose_index(
            policy_set,
            self.theta(policy_set),
            safety,
            choice,
            lane_change_bias,
            heading,
            stopping,
            braking,
            distance,
            in_lane=in_lane,
        )

    def __repr__(self) -> str:
        where = f", checkpoint={str(self.checkpoint)!r}" if self.checkpoint is not None else ""
        return f"LearnedReward({self.name!r}{where})"


def model_names() -> tuple[str, ...]:
    """Everything :func:`load_reward` accepts by name: 'expert', 'expert-theta' and the trained models."""
    from irlsim.models.registry import MODEL_NAMES  # lazy: pulls torch (~1.5 s); the expert drives without it

    return (EXPERT, EXPERT_THETA, *MODEL_NAMES)


def load_reward(
    spec: str | Path,
    runs: str | Path | None = None,
    *,
    n_policies: int | None = None,
    threads: int = 1,
) -> LearnedReward:
    """The reward of ``spec``: 'expert', 'expert-theta', a model name (LIRL, 1DCNN, Bi1DCNN, PACNN,
    PACNN+S, PTACNN, PTACNN+S; found in ``runs`` by :func:`irlsim.train.layout.find_checkpoint`:
    ``<runs>/stage1/<name>/``, ``<runs>/stage2/<name>/`` or ``<runs>/<name>/``) or a checkpoint path
    (``.../checkpoint.pt``) -- what ``irlsim drive --model`` accepts.

    ``n_policies``: the planner's policies per cycle; a checkpoint trained on another count is refused
    (the networks are built for the training set's N). ``threads``: torch CPU threads of the inference.
    Raises :class:`~irlsim.errors.IrlsimError` (one line) for an unknown name or a missing checkpoint.
    """
    # lazy: these import torch (~1.5 s); the expert and expert-theta drive without it
    from irlsim.models.registry import MODEL_NAMES
    from irlsim.reward.predictor import RewardPredictor
    from irlsim.train.layout import find_checkpoint, model_stage, stage_dir

    spec = str(spec)
    if spec == EXPERT:
        return LearnedReward(EXPERT)
    if spec == EXPERT_THETA:
        return LearnedReward(EXPERT_THETA, FixedTheta())
    if spec in MODEL_NAMES:
        if runs is None:
            raise IrlsimError(f"model '{spec}' needs --runs (the runs folder 'irlsim train --out' wrote)")
        found = find_checkpoint(runs, spec)
        if found is None:
            stage = model_stage(spec)
            raise IrlsimError(
                f"checkpoint {stage_dir(runs, stage) / spec / 'checkpoint.pt'} not found: run 'irlsim train "
                f"--stage {stage} --out {runs}' first (or point --runs at the folder holding it)"
            )
        path = found
    else:
        path = Path(spec)
        if not (path.suffix == ".pt" or "/" in spec):
            raise IrlsimError(
                f"unknown model '{spec}': choose from {', '.join(model_names())} or give a checkpoint path"
            )
        if not path.is_file():
            raise IrlsimError(f"checkpoint {path} not found: run 'irlsim train' first (or fix the path)")
    predictor = RewardPredictor(path, threads=threads)
    ck = predictor.loaded.checkpoint
    trained_n = int((ck.get("base") or ck).get("n_policies", 0))
    if n_policies is not None and trained_n and trained_n != n_policies:
        raise IrlsimError(
            f"{predictor.name} ({path}) was trained on {trained_n} policies per cycle, but the planner "
            f"samples {n_policies}: pass the collect --config the model was trained on"
        )
    return LearnedReward(predictor.name, predictor, path)


def check_features(reward: LearnedReward, features: tuple[str, ...] | list[str]) -> None:
    """Refuse (one line) a learned reward whose checkpoint weighs other features than ``features`` (the
    planner's, ``planner.feature_set``): its theta weighs the features by position. The expert and
    'expert-theta' take any set (their weights are named)."""
    ck = reward.trained
    if ck is None:
        return
    names = list((ck.get("base") or {}).get("feature_names") or ck.get("feature_names") or FEATURE_NAMES)
    if names != list(features):
        trained, here = feature_set_of(names) or "another", feature_set_of(features) or "another"
        raise IrlsimError(
            f"{reward.name} ({reward.checkpoint}) was trained on the '{trained}' feature set ({len(names)} "
            f"features), the planner computes the '{here}' set ({len(features)}): pass the collect --config "
            f'the model was trained on (planner.feature_set = "{trained}")'
        )

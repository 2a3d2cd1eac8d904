"""Config dataclasses of the two training stages (load with ``irlsim.config.load_config(cls, path)``).

TOML layout: top-level keys are the fields below; network sizes go in a ``[model]`` table
(see :class:`irlsim.models.ModelConfig`). ``Stage1Config.smoke()`` / ``Stage2Config.smoke()`` are the tiny
presets the tests use.
"""

from __future__ import annotations

from dataclasses import dataclass, field

from irlsim.config import MAX_SEED, STORED_IF_SET, require
from irlsim.models.networks import ENCODER_LAYOUTS
from irlsim.models.registry import MODEL_NAMES, STAGE1_MODELS, STAGE2_BASE, ModelConfig

SELECT_METRICS = ("val/opd", "val/ed", "val/nll", "last")
"""What ``select_by`` may name: a validation metric (lower is better) or 'last' (the final epoch)."""

LR_SCHEDULES = ("constant", "cosine")
FIXED_N_MODELS = ("1DCNN", "Bi1DCNN")
"""Stage-1 models whose first layer is sized by the policy count N (no ``policy_sample``)."""
"""What ``lr_schedule`` may name (stage 1)."""

#: metadata of an option added after checkpoints existed: stored in configs only when set
_IF_SET = {STORED_IF_SET: True}


#: the most torch CPU threads a config may ask (the --threads options' bound): more fail to start
MAX_THREADS = 1024


@dataclass(frozen=True)
class TrainConfig:
    """The fields both stages share (the stage configs below add their own)."""

    models: tuple[str, ...] = ()
    """which models to train (each into <runs>/stage<N>/<model>/)"""
    epochs: int = 20
    """passes over the train split"""
    batch_size: int = 32
    """planning cycles (stage 1) or histories (stage 2) per mini-batch"""
    lr: float = 1e-3
    """Adam learning rate"""
    weight_decay: float = 0.0
    """Adam (L2) weight decay"""
    grad_clip: float = 10.0
    """max gradient norm per step (0 = no clipping)"""
    validate_every: int = 5
    """[epochs] validation (ED, OPD on the sequential validation split) every this many epochs"""
    select_by: str = "val/opd"
    """model selection: inference (evaluate, drive, the frozen base of stage 2) uses the weights of the
    validated epoch with the lowest value of this metric ('val/opd', 'val/ed', 'val/nll'), or 'last' for
    the final epoch; resuming always continues from the final epoch"""
    seed: int = 0
    """seed of the weight initialisation and the shuffling"""
    threads: int = 2
    """torch CPU threads (torch.set_num_threads). Part of what decides the trained bytes: another count
    changes the float summation order, so the same seed gives slightly different weights (recorded in the
    checkpoint's 'provenance')"""
    max_cycles: int = 0
    """use only the first this many cycles of the train split (0 = all)"""
    safe_demos: bool = True
    """train on demonstrations that are never labelled as a predicted collision: such a demonstration
    moves to the closest policy (stored distance to the odometry) without the label, or the cycle is
    dropped when none is within 1.5 m (irlsim.data.demos.safe_demo_index; a closed-loop fix). On by default;
    false gives the paper's plain odometry projection. The train split only: validation and test
    metrics are distances to the odometry either way"""
    stop_demos: bool = True
    """train on demonstrations that never cross an active stop line without having stood (stop_line
    feature > 0): the demonstrator stood at every line, but the odometry's closest policy can creep over
    it; such a demonstration moves like a safe_demos one (with safe_demos: to the closest policy breaking
    neither rule; irlsim.data.demos.safe_demo_index; a closed-loop fix). On by default. The train split
    only"""
    eval_batch: int = 64
    """cycles per forward pass when predicting whole splits (memory bound)"""
    tensorboard: bool = True
    """also log to <out>/<model>/tensorboard if tensorboard is installed (silently skipped otherwise)"""
    model: ModelConfig = field(default_factory=ModelConfig)
    """network sizes"""

    def validate(self) -> None:
        require(len(self.models) >= 1, "models is empty: name at least one model to train")
        require(len(set(self.models)) == len(self.models), f"models {list(self.models)} names a model twice")
        require(0 <= self.seed <= MAX_SEED, f"seed must be in 0..{MAX_SEED}, got {self.seed}")
        require(self.epochs >= 0, "epochs must be >= 0")
        require(self.batch_size >= 1, "batch_size must be >= 1")
        require(self.lr > 0, "lr must be > 0")
        require(self.weight_decay >= 0, "weight_decay must be >= 0")
        require(self.grad_clip >= 0, "grad_clip must be >= 0")
        require(self.validate_every >= 1, "validate_every must be >= 1")
        require(self.select_by in SELECT_METRICS, f"select_by must be one of {', '.join(SELECT_METRICS)}")
        require(
            1 <= self.threads <= MAX_THREADS,
            f"threads must be in 1..{MAX_THREADS} (torch CPU threads, as --threads), got {self.threads}",
        )
        require(self.max_cycles >= 0, "max_cycles must be >= 0")
        require(self.eval_batch >= 1, "eval_batch must be >= 1")
        self.model.validate()


@dataclass(frozen=True)
class Stage1Config(TrainConfig):
    """Stage 1: LIRL and the per-cycle deep models, trained on the (shuffled) train split."""

    models: tuple[str, ...] = STAGE1_MODELS
    """which stage-1 models to train (each into <runs>/stage1/<model>/)"""
    attention_loss_weight: float = 1.0
    """weight of the semi-supervised attention loss of PACNN+S (L1 distance, in [0, 2])"""
    attention_tau: float = 0.5
    """[m] temperature of the attention target softmax(-distance / tau) of PACNN+S"""
    history: int = 10
    """[cycles] H: validation uses the mean of the last H predicted thetas within an episode"""
    encoder_layout: str = field(default="channels_first", metadata=_IF_SET)
    """memory layout of the policy encoder's computation: 'channels_first' (torch's Conv1d on the
    transposed [B, D, N] batch) or 'channels_last' (the same convs as matrix products on the policy-major
    [B, N, D] batch; measured slower on the 2-core CPU of docs/results/throughput.md, an option for other
    hardware);
    same weights and function, the bytes differ by float rounding (irlsim.models.networks.PolicyEncoder).
    Inference always uses the default"""
    lr_schedule: str = field(default="constant", metadata=_IF_SET)
    """'constant' (lr throughout) or 'cosine' (lr decays per step along a half cosine to 0 at the
    last step of ``epochs``; decided by the step's position alone, so a resumed run continues it)"""
    init_from: str = field(default="", metadata=_IF_SET)
    """warm start: a stage-1 checkpoint of the same model and sizes whose inference weights
    (the validation-selected epoch) and feature normalisation initialise the network, e.g. the previous
    DAgger round's reward; '' = random initialisation. Refused (one line) for another model, other
    sizes or another policy count. Ignored when resuming (the checkpoint's own weights continue); the
    checkpoint records it under 'warm_start'"""
    policy_sample: int = field(default=0, metadata=_IF_SET)
    """train each step on a sample of every cycle's policies: the demonstration and policy_sample - 1 of the
    others drawn uniformly (a fresh draw each step, from the seed and the epoch), in their progress order,
    importance-weighted in the max-ent normaliser (irlsim.irl.objectives.sample_policies). The network
    sees the sample only, so a step costs about policy_sample / N of the full set's. 0 (or >= N) = every
    policy. Validation, evaluation and driving use every policy. LIRL, PACNN and PACNN+S only (1DCNN and
    Bi1DCNN are built for a fixed N)"""

    def validate(self) -> None:
        require(
            self.policy_sample == 0 or self.policy_sample >= 2,
            f"policy_sample must be 0 (every policy) or >= 2 (the demonstration and one other), "
            f"got {self.policy_sample}",
        )
        fixed = [m for m in self.models if m in FIXED_N_MODELS]
        require(
            self.policy_sample == 0 or not fixed,
            f"policy_sample needs models that take any number of policies; {', '.join(fixed)} "
            "are built for a fixed N: train them in a run without policy_sample",
        )
        for m in self.models:
            require(m in STAGE1_MODELS, f"models: '{m}' is not a stage-1 model ({', '.join(STAGE1_MODELS)})")
        require(self.attention_loss_weight >= 0, "attention_loss_weight must be >= 0")
        require(self.attention_tau > 0, "attention_tau must be > 0 [m]")
        require(self.history >= 1, "history must be >= 1")
        require(
            self.encoder_layout in ENCODER_LAYOUTS,
            f"encoder_layout must be one of {', '.join(ENCODER_LAYOUTS)}, got '{self.encoder_layout}'",
        )
        require(
            self.lr_schedule in LR_SCHEDULES,
            f"lr_schedule must be one of {', '.join(LR_SCHEDULES)}, got '{self.lr_schedule}'",
        )
        super().validate()

    @classmethod
    def smoke(cls) -> Stage1Config:
        return cls(
            epochs=3,
            batch_size=8,
            lr=1e-2,
            validate_every=1,
            threads=1,
            tensorboard=False,
            model=ModelConfig(
                hidden_channels=8,
                latent=8,
                attention_hidden=4,
                head_hidden=16,
                fc_hidden=16,
                lstm_hidden=8,
                tan_fc_hidden=8,
            ),
        )


@dataclass(frozen=True)
class Stage2Config(TrainConfig):
    """Stage 2: PTACNN(+S) on the frozen PACNN(+S) of stage 1, trained with the NLL of cycle t+1."""

    models: tuple[str, ...] = tuple(STAGE2_BASE)
    """which stage-2 models to train, each into <runs>/stage2/<model>/ (PTACNN needs <base>/PACNN, PTACNN+S
    needs <base>/PACNN+S; <base> = <runs>/stage1 unless 'irlsim train --base' names another folder)"""
    batch_size: int = 64
    """histories per mini-batch"""
    model: ModelConfig = field(default_factory=ModelConfig)
    """sizes of the temporal network (lstm_hidden, lstm_layers, tan_fc_hidden, history = H [cycles]);
    the context size comes from the frozen PACNN checkpoint; tan_inputs and drop_newest (the
    temporal-attention study)"""
    target_ahead: int = 1
    """[cycles] training target: the mean NLL of cycles t+1 .. t+target_ahead given the history ending at t
    (1 = the paper's next cycle; pairs leaving the episode or without a demonstration are skipped)"""
    weight_reg: float = 0.0
    """weight of a regulariser on the temporal softmax w [H] (0 = none), see weight_reg_kind"""
    weight_reg_kind: str = "kl_uniform"
    """'kl_uniform': KL(uniform || w) = -log H - mean_h log w_h (pulls w towards the H-mean of the stage-1
    models); 'entropy': -entropy(w) = sum_h w_h log w_h (rewards spread weights); both are 0 at uniform w"""

    def validate(self) -> None:
        for m in self.models:
            require(m in STAGE2_BASE, f"models: '{m}' is not a stage-2 model ({', '.join(STAGE2_BASE)})")
        require(self.target_ahead >= 1, f"target_ahead must be >= 1 cycle, got {self.target_ahead}")
        require(self.weight_reg >= 0, f"weight_reg must be >= 0, got {self.weight_reg}")
        require(
            self.weight_reg_kind in ("kl_uniform", "entropy"),
            f"weight_reg_kind must be 'kl_uniform' or 'entropy', got '{self.weight_reg_kind}'",
        )
        super().validate()

    @property
    def history(self) -> int:
        return self.model.history

    @classmethod
    def smoke(cls) -> Stage2Config:
        return cls(
            epochs=3,
            batch_size=16,
            lr=1e-2,
            validate_every=1,
            threads=1,
            tensorboard=False,
            model=ModelConfig(lstm_hidden=8, tan_fc_hidden=8, history=4),
        )


assert set(STAGE1_MODELS) | set(STAGE2_BASE) == set(MODEL_NAMES)

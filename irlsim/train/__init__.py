"""Training loops of the two stages (evaluation, Table I, is :mod:`irlsim.evaluate`).

Stage 1 (:func:`train_stage1`): LIRL, 1DCNN, Bi1DCNN, PACNN, PACNN+S on the train split.
Stage 2 (:func:`train_stage2`): PTACNN, PTACNN+S on the frozen PACNN / PACNN+S.
A trained model's online reward is :mod:`irlsim.reward`.
"""

from irlsim.train.checkpoint import read_checkpoint
from irlsim.train.config import Stage1Config, Stage2Config
from irlsim.train.loading import LoadedModel, load_model
from irlsim.train.stage1 import train_stage1
from irlsim.train.stage2 import train_stage2

__all__ = [
    "LoadedModel",
    "load_model",
    "read_checkpoint",
    "Stage1Config",
    "Stage2Config",
    "train_stage1",
    "train_stage2",
]

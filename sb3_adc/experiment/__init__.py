"""
Experiments in the RL-Zoo log layout: training with checkpoints and resume (:mod:`~sb3_adc.experiment.training`),
playing trained models (:mod:`~sb3_adc.experiment.enjoy`), benchmark grids (:mod:`~sb3_adc.experiment.benchmark`)
and their statistics and plots (:mod:`~sb3_adc.experiment.plots`).
"""

from sb3_adc.experiment.evaluation import FinalEvaluation
from sb3_adc.experiment.layout import RunLayout, RunLocked, env_name
from sb3_adc.experiment.manager import RunInterrupted
from sb3_adc.experiment.settings import TrainSettings
from sb3_adc.experiment.training import TrainResult, find_run, resume, train

__all__ = [
    "FinalEvaluation",
    "RunInterrupted",
    "RunLayout",
    "RunLocked",
    "TrainResult",
    "TrainSettings",
    "env_name",
    "find_run",
    "resume",
    "train",
]

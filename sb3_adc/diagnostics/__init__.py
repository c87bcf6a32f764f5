"""
Critic diagnostics for any TD3-family model (:class:`~sb3_adc.ADC`, SB3's TD3 and DDPG,
:class:`~sb3_adc.baselines.SplitRateDDPG`): the critic's estimation bias against discounted Monte-Carlo returns
(:func:`evaluate_critic`, the TD3 paper's over-estimation measure), how strongly it pushes the actor
(:func:`gradient_norms`) and, for ADC's dueling interval critic, its interval visits and the advantage's
roughness across intervals (:func:`interval_visits`, :func:`advantage_roughness`). :class:`CriticDiagnosticsCallback`
logs them during training and keeps their history (:func:`save_history`, :func:`load_history`);
:func:`plot_diagnostics` draws several models' histories (``experiment`` extra). See the user guide's page.

The callback and its measures are in :mod:`sb3_adc.diagnostics.critic`, the history in
:mod:`sb3_adc.diagnostics.history`.
"""

from sb3_adc.diagnostics.critic import (
    EVAL_KEYS,
    GRADIENT_KEYS,
    INTERVAL_KEYS,
    CriticDiagnosticsCallback,
    advantage_roughness,
    batch_diagnostics,
    discounted_returns,
    evaluate_critic,
    gradient_norms,
    interval_visits,
    is_interval_critic,
    truncation_weights,
)
from sb3_adc.diagnostics.history import (
    ADVANTAGE_PROFILE_KEY,
    ARRAY_KEYS,
    HISTORY_CSV,
    HISTORY_NPZ,
    INTERVAL_VISITS_KEY,
    History,
    load_history,
    plot_diagnostics,
    save_history,
)

__all__ = [
    "ADVANTAGE_PROFILE_KEY",
    "ARRAY_KEYS",
    "EVAL_KEYS",
    "GRADIENT_KEYS",
    "HISTORY_CSV",
    "HISTORY_NPZ",
    "INTERVAL_KEYS",
    "INTERVAL_VISITS_KEY",
    "CriticDiagnosticsCallback",
    "History",
    "advantage_roughness",
    "batch_diagnostics",
    "discounted_returns",
    "evaluate_critic",
    "gradient_norms",
    "interval_visits",
    "is_interval_critic",
    "load_history",
    "plot_diagnostics",
    "save_history",
    "truncation_weights",
]

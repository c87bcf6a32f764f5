"""
Critic diagnostics of TD3-family models (ADC, TD3, DDPG, SplitRateDDPG), measured by :mod:`sb3_adc.diagnostics.critic`
and logged by :class:`CriticDiagnosticsCallback` into a history (:mod:`sb3_adc.diagnostics.history`); see the guide.
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

__all__ = ["ADVANTAGE_PROFILE_KEY", "ARRAY_KEYS", "EVAL_KEYS", "GRADIENT_KEYS", "HISTORY_CSV", "HISTORY_NPZ", "INTERVAL_KEYS"]
__all__ += ["INTERVAL_VISITS_KEY", "CriticDiagnosticsCallback", "History", "advantage_roughness", "batch_diagnostics"]
__all__ += ["discounted_returns", "evaluate_critic", "gradient_norms", "interval_visits", "is_interval_critic", "load_history"]
__all__ += ["plot_diagnostics", "save_history", "truncation_weights"]

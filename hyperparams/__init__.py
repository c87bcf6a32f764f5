"""RL-Zoo-format hyperparameter files (one YAML per algorithm), shipped inside the package."""

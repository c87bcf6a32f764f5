"""``python -m sb3_adc.zoo train|enjoy ...``: the RL Zoo with sb3-adc's algorithms and hyperparameters."""

from sb3_adc.zoo import main

raise SystemExit(main())

"""``python -m sb3_adc``: the ``sb3-adc`` command."""

from sb3_adc.cli import main

raise SystemExit(main())

"""Building blocks shared by the sb3-adc algorithms."""

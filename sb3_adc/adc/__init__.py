from sb3_adc.adc.adc import ADC
from sb3_adc.adc.policies import ADCPolicy, CnnPolicy, DuelingIntervalCritic, MlpPolicy, MultiInputPolicy

__all__ = ["ADC", "ADCPolicy", "CnnPolicy", "DuelingIntervalCritic", "MlpPolicy", "MultiInputPolicy"]

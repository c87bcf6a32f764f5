"""Learning-rate schedules."""

from __future__ import annotations

from stable_baselines3.common.type_aliases import Schedule


class ScaledSchedule:
    """
    A schedule multiplied by a constant factor: ``ScaledSchedule(schedule, 2.0)(p) == 2.0 * schedule(p)``.

    ADC uses it for its default critic learning rate, twice the actor's at every point of training
    (the ratio of the ADC paper's Tables 1-3).

    :param schedule: The schedule to scale (a function of the progress remaining, from 1 to 0)
    :param factor: The constant factor
    """

    def __init__(self, schedule: Schedule, factor: float):
        self.schedule = schedule
        self.factor = float(factor)

    def __call__(self, progress_remaining: float) -> float:
        return self.factor * float(self.schedule(progress_remaining))

    def __repr__(self) -> str:
        return f"ScaledSchedule({self.schedule!r}, factor={self.factor})"

"""The one schedule of the evaluation, checkpoint and trial callbacks: multiples of a timestep interval."""

import pytest

from sb3_adc.experiment.callbacks import TimestepSchedule


def due_timesteps(schedule: TimestepSchedule, start: int, stop: int, n_envs: int) -> list[int]:
    """The timestep counts at which the schedule acts while training goes from ``start`` to ``stop``."""
    schedule.start(start)
    return [steps for steps in range(start + n_envs, stop + 1, n_envs) if schedule.due(steps)]


@pytest.mark.parametrize("n_envs", [1, 3, 4])
def test_acts_once_per_interval_at_the_first_count_past_each_multiple(n_envs):
    acted = due_timesteps(TimestepSchedule(10), 0, 60, n_envs)
    assert len(acted) == 6  # 60 is a count every n_envs reaches
    for steps, multiple in zip(acted, range(10, 61, 10), strict=False):
        assert multiple <= steps < multiple + n_envs


@pytest.mark.parametrize("resume_at", [0, 12, 20, 36])
def test_a_resumed_run_acts_at_the_timesteps_of_an_uninterrupted_one(resume_at):
    uninterrupted = due_timesteps(TimestepSchedule(10), 0, 80, 4)
    resumed = due_timesteps(TimestepSchedule(10), resume_at, 80, 4)
    assert resumed == [steps for steps in uninterrupted if steps > resume_at]
    assert resumed  # the comparison is not vacuous

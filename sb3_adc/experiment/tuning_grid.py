"""
Equal-budget tuning as data: the ``tuning:`` key of an experiment file, which makes the file one Optuna study per
configuration (:func:`~sb3_adc.experiment.tuning.tune`, ``sb3-adc train -optimize``'s engine) instead of a grid::

    envs: [sb3_adc/NoisyPendulum-v1]          # exactly one
    seeds: [0, 1]                             # the tuning seeds: every trial trains on each
    n_timesteps: 20000                        # every run's budget (null: each entry's)
    evaluation: {episodes: 5, final_episodes: 10}   # each pruner evaluation; the final one (a trial's value)
    configs:                                  # the starting entry (trial 0) is the config's entry
      adc: {algo: adc, hyperparams: ../configs/warmup5000, search_space: {buffer_size: [50000, 200000]}}
    tuning:
      trials: 6                               # finished trials per study, the starting entry included
      objective: return                       # or success
      sampler: tpe                            # optional: tpe (default) or random; sampler_seed (0)
      pruner: median                          # optional: median (default), halving or none
      n_startup_trials: 3                     # optional (default 3)
      n_evaluations: 5                        # optional (default 5): evaluations per run reported to the pruner
      fixed: {gamma: 0.98}                    # optional: -params of every trial, outside the search
      eval_env_kwargs: {layout_seeds: [2000000, 2000100]}  # optional: the evaluations' gym.make keywords

A configuration's ``search_space`` (choices per key) is searched beside its algorithm's own space, and its
``overrides`` are fixed like ``fixed``. The studies go to ``{runs}/tuning/{config}-{env}/`` (re-running the file
resumes them; ``--workers``: each study's worker processes); the results folder gets each ``{config}/trials.csv``,
the winners as ``hyperparams/{config}.yml``, ``summary.md`` and ``metadata.json``.
"""

from __future__ import annotations

import contextlib
import csv
import dataclasses
import os
import shutil
import tempfile
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

from sb3_adc.config import HyperparamsError, load_hyperparams
from sb3_adc.experiment.layout import FolderLock, env_name
from sb3_adc.experiment.provenance import machine_metadata
from sb3_adc.experiment.test_sets import is_int
from sb3_adc.experiment.tuning_settings import TuneSettings, check_search_space

if TYPE_CHECKING:
    from sb3_adc.experiment.experiments import Experiment

#: The key of the file behind each option that :class:`~sb3_adc.experiment.tuning_settings.TuneSettings` refuses.
OPTION_KEYS = {"--n-trials": "tuning.trials", "--n-startup-trials": "tuning.n_startup_trials"}
OPTION_KEYS |= {"--n-evaluations": "tuning.n_evaluations", "--sampler": "tuning.sampler", "--pruner": "tuning.pruner"}
OPTION_KEYS |= {"--objective": "tuning.objective", "--tuning-seeds": "seeds", "--n-timesteps": "n_timesteps"}
OPTION_KEYS |= {"--eval-episodes": "evaluation.episodes", "--final-eval-episodes": "evaluation.final_episodes"}
#: Trials of each study under ``--tiny``.
TINY_TRIALS = 2


@dataclass(frozen=True)
class Tuning:
    """
    The ``tuning:`` key of an experiment file (see the module's docstring), with its defaults.

    :param trials: Finished trials per study
    :param objective: ``return`` or ``success``
    :param sampler: ``tpe`` or ``random``
    :param pruner: ``median``, ``halving`` or ``none``
    :param sampler_seed: Seed of the sampler (worker ``k``: ``sampler_seed + k``)
    :param n_startup_trials: Random trials before TPE takes over and the median pruner prunes
    :param n_evaluations: Evaluations per run reported to the pruner
    :param fixed: ``-params`` of every trial
    :param eval_env_kwargs: ``gym.make`` keywords of the evaluations
    :param search_spaces: Configuration name -> its choices per key
    """

    trials: int
    objective: str = "return"
    sampler: str = "tpe"
    pruner: str = "median"
    sampler_seed: int = 0
    n_startup_trials: int = 3
    n_evaluations: int = 5
    fixed: dict[str, Any] = field(default_factory=dict)
    eval_env_kwargs: dict[str, Any] = field(default_factory=dict)
    search_spaces: dict[str, dict[str, list[Any]]] = field(default_factory=dict)


#: Keys of ``tuning:``.
TUNING_KEYS = tuple(key.name for key in dataclasses.fields(Tuning) if key.name != "search_spaces")


def read_tuning(data: Mapping[str, Any], experiment: Experiment) -> Tuning | None:
    """
    The ``tuning:`` key of a file (``None`` without one), its values checked by each configuration's
    :class:`~sb3_adc.experiment.tuning_settings.TuneSettings`.

    :param data: The file's mapping
    :param experiment: The file's other keys, read and checked
    :raises ExperimentError: naming the key of the file that a study's settings refuse
    """
    from sb3_adc.experiment.experiments import ExperimentError, _check_keys, _require

    path, value = experiment.path, data.get("tuning")
    spaces = {name: (data["configs"][name] or {}).get("search_space") for name in experiment.configs}
    if value is None:
        for name, space in spaces.items():
            _require(space is None, path, f"configs.{name}.search_space", "needs the file's `tuning:` key")
        return None
    _check_keys(value, TUNING_KEYS, path, "tuning")
    _require("trials" in value, path, "tuning.trials", "is required: the finished trials of each study")
    for key in ("fixed", "eval_env_kwargs"):
        _require(isinstance(value.get(key, {}), Mapping), path, f"tuning.{key}", "must be a mapping")
    _require(is_int(value.get("sampler_seed", 0), 0, 2**31), path, "tuning.sampler_seed", "must be an integer >= 0")
    _require(len(experiment.envs) == 1, path, "envs", "must name exactly one env in a tuning file")
    tuning = Tuning(**value, search_spaces={name: space or {} for name, space in spaces.items()})
    for name in experiment.configs:
        try:
            study_settings(dataclasses.replace(experiment, tuning=tuning), name)
        except HyperparamsError as error:
            option = str(error.key)
            where = "algo" if option == "--algo" else "search_space"
            raise ExperimentError(path, OPTION_KEYS.get(option, f"configs.{name}.{where}"), error.problem) from None
    return tuning


def study_settings(
    experiment: Experiment, name: str, workers: int = 1, tiny: bool = False, runs: str | None = None
) -> TuneSettings:
    """
    The study of one configuration of a tuning file.

    :param experiment: The file (with ``tuning:``)
    :param name: The configuration (its study is ``{name}-{env}``, in ``{runs}/tuning/``)
    :param workers: Worker processes
    :param tiny: :data:`TINY_TRIALS` trials of the tiny budget on the first seed, one episode per evaluation
    :param runs: Folder of the studies instead of the file's runs folder
    :raises HyperparamsError: naming the option of a setting it refuses
    """
    from sb3_adc.experiment.experiments import TINY_TIMESTEPS

    tuning, config, env_id = experiment.tuning, experiment.configs[name], experiment.envs[0]
    assert tuning is not None, f"{experiment.path} has no tuning"
    same = ("sampler", "pruner", "n_startup_trials", "n_evaluations", "objective", "sampler_seed")
    return TuneSettings(
        **{key: getattr(tuning, key) for key in same},
        algo=config.algo,
        env_id=env_id,
        conf_file=None if config.hyperparams is None else os.path.join(config.hyperparams, f"{config.algo}.yml"),
        n_trials=TINY_TRIALS if tiny else tuning.trials,
        n_timesteps=TINY_TIMESTEPS if tiny else experiment.n_timesteps,
        seeds=tuple(experiment.seeds[:1] if tiny else experiment.seeds),
        eval_episodes=1 if tiny else experiment.eval_episodes,
        final_eval_episodes=1 if tiny else experiment.final_eval_episodes,
        n_jobs=workers,
        study_name=f"{name}-{env_name(env_id)}",
        overrides={**tuning.fixed, **config.overrides},
        eval_env_kwargs=dict(tuning.eval_env_kwargs),
        search_space=dict(tuning.search_spaces[name]),
        log_folder=runs or experiment.runs,
        device="cpu",
    )


def record(experiment: Experiment, tiny: bool = False) -> dict[str, Any]:
    """
    The settings of a tuning file's studies, as its ``metadata.json`` records them (paths relative to the repository).

    :param experiment: The file (with ``tuning:``)
    :param tiny: The settings of ``--tiny``
    """
    from sb3_adc.experiment.experiments import repository_root

    studies = {name: study_settings(experiment, name, tiny=tiny) for name in experiment.configs}
    study, root = next(iter(studies.values())), repository_root(experiment)
    overrides = {name: config.overrides for name, config in experiment.configs.items() if config.overrides}
    return {
        "env": study.env_id,
        "seeds": list(study.seeds),
        "n_trials": study.n_trials,
        "n_timesteps": study.n_timesteps,
        "sampler": f"{study.sampler} ({study.n_startup_trials} random startup trials, seed {study.sampler_seed} + worker)",
        "pruner": f"{study.pruner} ({study.n_startup_trials} startup trials, {study.n_evaluations} evaluations of "
        f"{study.eval_episodes} episodes per run)",
        "objective": f"mean over the seeds of the final evaluation's {study.objective} "
        f"({study.final_eval_episodes} deterministic episodes)",
        "fixed": dict(experiment.tuning.fixed),  # type: ignore[union-attr]
        **({"overrides": overrides} if overrides else {}),
        "starting_points": {
            name: os.path.relpath(s.conf_file, root) if s.conf_file else f"hyperparams/{s.algo}.yml (shipped)"
            for name, s in studies.items()
        },
        "search_space": {name: s.search_space for name, s in studies.items()},
        "eval_env_kwargs": study.eval_env_kwargs,
        "experiment": os.path.relpath(experiment.path, root),
    }


def read_trials(trials_csv: str) -> list[dict[str, str]]:
    """The rows of a study's ``trials.csv`` in the results (none without one)."""
    if not os.path.isfile(trials_csv):
        return []
    with open(trials_csv, encoding="utf-8") as stream:
        return list(csv.DictReader(stream))


def finished(trials: list[dict[str, str]]) -> list[dict[str, str]]:
    """The trials that count towards the budget: complete or pruned."""
    return [row for row in trials if row["state"] in ("COMPLETE", "PRUNED")]


def summarise(experiment: Experiment, output: str, seeds: list[int]) -> tuple[list[str], dict[str, float]]:
    """
    Write ``summary.md`` for every configuration with a ``trials.csv`` in ``output``; return its lines and, per
    configuration, the summed duration of its finished trials in seconds (its compute, whatever the interruptions).

    :param experiment: The file (with ``tuning:``)
    :param output: Its results folder
    :param seeds: The tuning seeds
    """
    assert experiment.tuning is not None
    success = experiment.tuning.objective == "success"
    validation = " on validation layouts" if "layout_seeds" in experiment.tuning.eval_env_kwargs else ""
    quantity = f"success rate{validation}" if success else "return"
    summary = [
        f"| algorithm | finished trials | best trial | best mean final {quantity} (seeds {', '.join(map(str, seeds))}) |",
        "|---|---:|---|---:|",
    ]
    trial_time = {}
    for name in experiment.configs:
        trials = read_trials(os.path.join(output, name, "trials.csv"))
        if not trials:
            continue
        done = finished(trials)
        best = max((row for row in trials if row["state"] == "COMPLETE"), key=lambda row: float(row["value"]))
        label = "starting entry" if best["shipped"] == "True" else f"trial {best['number']}"
        summary.append(f"| {name} | {len(done)} | {label} | {float(best['value']):.{2 if success else 1}f} |")
        trial_time[name] = round(sum(float(row["duration_s"] or 0.0) for row in done), 1)
    with open(os.path.join(output, "summary.md"), "w", encoding="utf-8") as stream:
        stream.write("\n".join(summary) + "\n")
    return summary, trial_time


def run_tuning(experiment: Experiment, workers: int | None = None, tiny: bool = False) -> list[str]:
    """
    Run (or resume) the study of every configuration of a tuning file, one after the other, writing the results
    (``trials.csv``, the winners, ``summary.md``, ``metadata.json``) after every study.

    :param experiment: The file (with ``tuning:``)
    :param workers: Worker processes of each study (``None``: one)
    :param tiny: :data:`TINY_TRIALS` short trials per study in a temporary folder: a check that the file runs
    :return: The lines of the summary
    :raises HyperparamsError: for an entry or choice the loader refuses, before any study trains
    :raises RunLocked: if another invocation is working on the results folder or one of the studies
    """
    from sb3_adc.experiment.summary import read_metadata, write_metadata
    from sb3_adc.experiment.tuning import tune

    for name in experiment.configs:  # every study's entries and choices checked before any trains
        study = study_settings(experiment, name, tiny=tiny)
        load_hyperparams(study.algo, study.env_id, study.conf_file, study.overrides, study.n_timesteps)
        check_search_space(study)
    scratch = tempfile.TemporaryDirectory(prefix=f"{experiment.name}_tiny_") if tiny else contextlib.nullcontext("")
    lock = contextlib.nullcontext() if tiny else FolderLock(experiment.results, "running an experiment in it")
    with lock, scratch as folder:
        output = os.path.join(folder, "results") if folder else experiment.results
        os.makedirs(os.path.join(output, "hyperparams"), exist_ok=True)
        metadata_path = os.path.join(output, "metadata.json")
        metadata = read_metadata(metadata_path) or {"wall_time_s": {}}
        summary: list[str] = []
        for name in experiment.configs:
            study = study_settings(experiment, name, workers or 1, tiny, os.path.join(folder, "runs") if folder else None)
            result = tune(study)
            if result.n_finished > study.n_trials:
                raise RuntimeError(f"the {name} study holds {result.n_finished} trials, more than the budget {study.n_trials}")
            # The study's wall time is that of every invocation that trained it, one stopped by Ctrl-C or a kill
            # included (its journal: tune). An invocation that only reports (its study finished before) keeps the
            # workers and machine of the invocations that trained.
            trained = result.n_finished > len(finished(read_trials(os.path.join(output, name, "trials.csv"))))
            if trained:
                metadata["wall_time_s"][name] = result.wall_time_s
            invocation = {"workers": workers or 1, **machine_metadata()} if trained or "workers" not in metadata else {}
            os.makedirs(os.path.join(output, name), exist_ok=True)
            shutil.copyfile(os.path.join(result.study_dir, "trials.csv"), os.path.join(output, name, "trials.csv"))
            shutil.copyfile(result.best_hyperparams_file, os.path.join(output, "hyperparams", f"{name}.yml"))
            summary, trial_time = summarise(experiment, output, list(study.seeds))
            metadata.update({**record(experiment, tiny), "trial_time_s": trial_time, **invocation})
            write_metadata(metadata_path, metadata)
    return summary

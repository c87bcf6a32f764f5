"""
Held-out test sets of an experiment (its file's ``test_sets``): each finished run's final model (or
``best_model.zip``) plays deterministic episodes on settings it never trained on (the Procgen/MetaDrive protocol):
``env_kwargs`` over the run's, and ``layout_seeds`` (one episode per procedural layout, reset to and seeded by it),
``courses`` (course files, ``episodes`` each, seeded 0, 1, ...) or neither. An episode succeeds when its last
``info["is_success"]`` is true. Results: ``test_episodes.csv`` (per episode, with on the lidar courses what a failed
episode hit and whether it was unseen, :data:`SIGHTING`), ``test_runs.csv`` (:func:`run_rates`) and
``test_summary.{csv,md}`` (:func:`summary`). Scoring resumes: rows scored with a test set's settings (``test_sets.json``)
are kept.
"""

from __future__ import annotations

import json
import os
from collections import deque
from collections.abc import Mapping
from concurrent.futures import ProcessPoolExecutor
from dataclasses import asdict, dataclass, field, replace
from pathlib import Path
from typing import Any

import gymnasium as gym
import pandas as pd

#: Keys of one test set, and the models a test set can score.
TEST_SET_KEYS = ("env_kwargs", "layout_seeds", "courses", "episodes", "model")
MODELS = ("final", "best")
MAX_EPISODES = 100_000
EPISODES_CSV, RUNS_CSV, SUMMARY_CSV, SETTINGS_JSON = "test_episodes.csv", "test_runs.csv", "test_summary.csv", "test_sets.json"
RUN_KEYS = ["config", "env", "seed"]
#: A lidar course's failed episode hit an unseen obstacle when no ray met it in the scans from ``SIGHTING[1]`` to
#: ``SIGHTING[0]`` steps before the contact (the last 0.5 m of driving are too late to avoid it).
SIGHTING = (6, 10)


@dataclass(frozen=True)
class TestSet:
    """
    One held-out test set.

    :param env_kwargs: ``gym.make`` keywords over the run's entry's ``env_kwargs``
    :param layout_seeds: ``(start, stop)``: one episode per procedural layout seed (``None``: none)
    :param courses: Course files, ``episodes`` episodes each (``None``: none)
    :param episodes: Episodes per course, or of the test set without layouts and courses
    :param model: ``final`` or ``best`` (the run's ``best_model.zip``)
    """

    env_kwargs: dict[str, Any] = field(default_factory=dict)
    layout_seeds: tuple[int, int] | None = None
    courses: list[str] | None = None
    episodes: int = 1
    model: str = "final"

    def tiny(self) -> TestSet:
        """Two layouts, or one episode of the first course: the pipeline in seconds."""
        layouts = None if self.layout_seeds is None else (self.layout_seeds[0], self.layout_seeds[0] + 2)
        return replace(self, layout_seeds=layouts, courses=None if self.courses is None else self.courses[:1], episodes=1)

    def record(self) -> dict[str, Any]:
        """The settings as ``metadata.json`` and ``test_sets.json`` record them."""
        return json.loads(json.dumps(asdict(self)))


def is_int(value: Any, low: int, high: int) -> bool:
    """Whether ``value`` is an integer (not a bool) from ``low`` to ``high``: a count or a seed of a file's key."""
    return isinstance(value, int) and not isinstance(value, bool) and low <= value <= high


def read_test_sets(value: Any, path: str) -> dict[str, TestSet]:
    """
    The ``test_sets`` of an experiment file, checked.

    :param value: Test set name -> mapping of :data:`TEST_SET_KEYS` (``None``: none)
    :param path: The experiment file, named by the errors
    :raises ExperimentError: naming the key of anything it gets wrong
    """
    from sb3_adc.experiment.experiments import _require  # imported here: experiments imports this module

    if value is None:
        return {}
    valid = isinstance(value, Mapping) and 0 < len(value) <= 16
    _require(valid, path, "test_sets", "must map 1 to 16 names to test sets")
    sets = {}
    for name, spec in value.items():
        key = f"test_sets.{name}"
        valid = isinstance(name, str) and isinstance(spec, Mapping) and not set(spec) - set(TEST_SET_KEYS)
        _require(valid, path, key, f"must be named by a string and map some of {', '.join(TEST_SET_KEYS)}")
        kwargs, layouts, courses = spec.get("env_kwargs") or {}, spec.get("layout_seeds"), spec.get("courses")
        episodes, model = spec.get("episodes", 1), spec.get("model", "final")
        valid = isinstance(kwargs, Mapping) and all(isinstance(k, str) for k in kwargs)
        _require(valid, path, f"{key}.env_kwargs", "must be a mapping of gym.make keywords")
        if layouts is not None:
            bounds: Any = (layouts.get("start"), layouts.get("stop")) if isinstance(layouts, Mapping) else (None, None)
            start, stop = bounds
            valid = is_int(start, 0, 2**31) and is_int(stop, 0, 2**31) and 0 < stop - start <= MAX_EPISODES
            _require(valid, path, f"{key}.layout_seeds", f"must be {{start: int, stop: int}}, 1 to {MAX_EPISODES} seeds")
            layouts = (int(start), int(stop))
        if courses is not None:
            valid = layouts is None and isinstance(courses, list) and bool(courses)
            _require(valid, path, f"{key}.courses", "must list course names, and not go with layout_seeds")
            _require(all(isinstance(c, str) and c for c in courses), path, f"{key}.courses", "must list course names")
        valid = is_int(episodes, 1, MAX_EPISODES) and not (layouts is not None and "episodes" in spec)
        _require(valid, path, f"{key}.episodes", f"must be in 1-{MAX_EPISODES} (one per layout seed with layout_seeds)")
        _require(model in MODELS, path, f"{key}.model", f"must be one of {', '.join(MODELS)}")
        sets[name] = TestSet(dict(kwargs), layouts, None if courses is None else list(courses), episodes, model)
    return sets


def _contact(env: gym.Env, scans: deque[set[int]]) -> tuple[str, bool]:
    """On a lidar course, what the robot ended against (kinds joined by ``;``) and whether an obstacle of them was
    unseen (:data:`SIGHTING`); ``("", False)`` elsewhere."""
    course: Any = env.unwrapped
    simulation = getattr(course, "simulation", None)
    if simulation is None or not hasattr(simulation, "touched_bodies"):
        return "", False
    touched = simulation.touched_bodies(*course.pose[:2])
    seen = set().union(*list(scans)[: len(scans) - SIGHTING[0]])
    return ";".join(sorted(set(simulation.body_kinds(touched)))), bool(set(touched) & set(simulation.obstacle_ids) - seen)


def play_episode(model: Any, env: gym.Env, **reset: Any) -> dict[str, Any]:
    """
    One deterministic episode: ``success``, ``return``, ``length``, and on the lidar courses ``hit``, ``hit_unseen``.

    :param model: Anything with SB3's ``predict``
    :param env: The environment
    :param reset: Keywords of ``env.reset``
    """
    observation, _ = env.reset(**reset)
    simulation: Any = getattr(env.unwrapped, "simulation", None)
    ray_bodies = (lambda: set(simulation.ray_bodies)) if hasattr(simulation, "ray_bodies") else set
    scans: deque[set[int]] = deque([ray_bodies()], maxlen=SIGHTING[1] + 1)
    total, length = 0.0, 0
    while True:
        action, _ = model.predict(observation, deterministic=True)
        observation, reward, terminated, truncated, info = env.step(action)
        total, length = total + float(reward), length + 1
        scans.append(ray_bodies())
        if terminated or truncated:
            success = bool(info.get("is_success", False))
            hit, unseen = ("", False) if success else _contact(env, scans)
            return {"success": success, "return": total, "length": length, "hit": hit, "hit_unseen": unseen}


def score_run(run_dir: str, run: dict[str, Any], test_sets: dict[str, TestSet]) -> list[dict[str, Any]]:
    """
    The episodes of one finished run on each test set.

    :param run_dir: The run's folder
    :param run: ``config``, ``env`` and ``seed``, copied into each row
    :param test_sets: Name -> test set
    """
    import torch as th

    from sb3_adc.experiment.enjoy import load_model, load_run, model_path

    th.set_num_threads(1)
    _, config, layout = load_run(run_dir)
    if config.normalize is not None or config.frame_stack is not None:
        raise ValueError(f"{run_dir}: test sets score entries without `normalize` and `frame_stack`")
    rows = []
    for name, test in test_sets.items():
        model = load_model(config, model_path(layout, test.model)[0], device="cpu")
        kwargs = {**config.env_kwargs, **test.env_kwargs}
        if test.layout_seeds is not None:
            resets = [("", {"seed": s, "options": {"layout_seed": s}}) for s in range(*test.layout_seeds)]
            kwargs["layout_seeds"] = test.layout_seeds
        else:
            resets = [(course, {"seed": k}) for course in test.courses or [""] for k in range(test.episodes)]
        envs: dict[str, gym.Env] = {}
        for episode, (course, reset) in enumerate(resets):
            if course not in envs:
                envs[course] = config.wrap_env(gym.make(run["env"], **{**kwargs, **({"course": course} if course else {})}))
            played = play_episode(model, envs[course], **reset)
            rows.append({**run, "test_set": name, "episode": episode, "course": course, **played})
        for env in envs.values():
            env.close()
    return rows


def run_rates(episodes: pd.DataFrame) -> pd.DataFrame:
    """
    Per run and test set: ``episodes``, ``successes``, ``success_rate``, ``mean_return``, and the failed episodes that
    ended against an obstacle (not a wall) and against one unseen (``hit_obstacle``, ``hit_unseen``).

    :param episodes: ``test_episodes.csv``
    """
    hit_obstacle = episodes["hit"].fillna("").map(lambda hit: bool(set(hit.split(";")) - {"", "wall"}))
    grouped = episodes.assign(hit_obstacle=hit_obstacle).groupby([*RUN_KEYS, "test_set"], sort=False)
    counts = {"episodes": ("success", "size"), "successes": ("success", "sum"), "mean_return": ("return", "mean")}
    rates = grouped.agg(**counts, hit_obstacle=("hit_obstacle", "sum"), hit_unseen=("hit_unseen", "sum")).reset_index()
    return rates.assign(success_rate=rates["successes"] / rates["episodes"])


def score(runs: dict[tuple[str, str, int], str], test_sets: dict[str, TestSet], output: str, workers: int = 1) -> None:
    """
    Score every run not yet scored with the test sets' current settings, then write ``test_episodes.csv``,
    ``test_runs.csv`` and ``test_sets.json`` in ``output``.

    :param runs: (config, env, seed) -> the finished run's folder
    :param test_sets: Name -> test set
    :param output: The experiment's results folder
    :param workers: Runs scored in parallel
    """
    path, settings_path = os.path.join(output, EPISODES_CSV), os.path.join(output, SETTINGS_JSON)
    recorded = json.loads(Path(settings_path).read_text(encoding="utf-8")) if os.path.isfile(settings_path) else {}
    table = pd.read_csv(path) if os.path.isfile(path) else pd.DataFrame(columns=[*RUN_KEYS, "test_set"])
    current = {name: test.record() for name, test in test_sets.items()}
    table = table[table["test_set"].map(lambda name: recorded.get(name) == current.get(name)).astype(bool)]
    done = set(zip(table["config"], table["env"], table["seed"].astype(int), table["test_set"], strict=True))
    todo = {run: {name: test for name, test in test_sets.items() if (*run, name) not in done} for run in runs}
    jobs = [(runs[run], dict(zip(RUN_KEYS, run, strict=True)), sets) for run, sets in todo.items() if sets]
    if workers > 1 and len(jobs) > 1:
        with ProcessPoolExecutor(max_workers=workers) as pool:
            scored = list(pool.map(score_run, *zip(*jobs, strict=True)))
    else:
        scored = [score_run(*job) for job in jobs]
    new = pd.DataFrame([row for rows in scored for row in rows])
    frames = [frame for frame in (table, new) if not frame.empty]
    if not frames:
        return
    table = pd.concat(frames, ignore_index=True)
    table = table.sort_values([*RUN_KEYS, "test_set", "episode"], kind="stable").reset_index(drop=True)
    os.makedirs(output, exist_ok=True)
    table.to_csv(path, index=False)
    run_rates(table).to_csv(os.path.join(output, RUNS_CSV), index=False)
    Path(settings_path).write_text(json.dumps(current, indent=2) + "\n", encoding="utf-8")


def summary(rates: pd.DataFrame, references: Mapping[str, str | None], reps: int) -> pd.DataFrame:
    """
    Per environment, test set and configuration: the IQM and mean of the runs' success rates with 95%
    stratified-bootstrap CIs, and P(its reference > configuration) with its CI (rliable, seed 0).

    :param rates: ``test_runs.csv``
    :param references: Configuration -> the configuration it is compared with (``None``: none)
    :param reps: Bootstrap replications
    """
    # Imported here: building the command line imports this module, and rliable comes with the `experiment` extra.
    from sb3_adc.experiment.statistics import final_performance, probability_of_improvement

    frames = []
    for (env, test_set), group in rates.groupby(["env", "test_set"], sort=False):
        scores = group.sort_values("seed", kind="stable")[["config", "seed", "success_rate"]].assign(env=test_set)
        scores = scores.rename(columns={"config": "algo", "success_rate": "mean_return"})
        table = final_performance(scores, reps=reps).rename(columns={"algo": "config"})
        table["reference"] = [references.get(name) for name in table["config"]]
        for position, (name, reference) in enumerate(zip(table["config"], table["reference"], strict=True)):
            if reference in set(scores["algo"]) and name != reference:
                pair = scores[scores["algo"].isin([reference, name])].replace({"algo": {reference: "x", name: "y"}})
                (row,) = probability_of_improvement(pair, reps=reps).to_dict("records")
                columns = ["p_reference", "p_reference_ci_low", "p_reference_ci_high"]
                table.loc[position, columns] = row["probability"], row["ci_low"], row["ci_high"]
        frames.append(table.assign(env=env, test_set=test_set))
    columns = ["env", "test_set", "config", "n_runs", "iqm", "iqm_ci_low", "iqm_ci_high", "mean", "mean_ci_low"]
    columns += ["mean_ci_high", "reference", "p_reference", "p_reference_ci_low", "p_reference_ci_high"]
    return pd.concat(frames, ignore_index=True).reindex(columns=columns)


def markdown(table: pd.DataFrame) -> str:
    """
    :func:`summary` as a Markdown table (2 decimals).

    :param table: The output of :func:`summary`
    """
    lines = [
        "| env | test set | configuration | runs | success IQM [95% CI] | mean [95% CI] | reference "
        "| P(reference > configuration) [95% CI] |",
        "|---|---|---|---:|---|---|---|---|",
    ]
    for row in table.itertuples(index=False):
        low, high = row.p_reference_ci_low, row.p_reference_ci_high
        p = "—" if pd.isna(row.p_reference) else f"{row.p_reference:.2f} [{low:.2f}, {high:.2f}]"
        lines.append(
            f"| {row.env} | {row.test_set} | {row.config} | {row.n_runs} | {row.iqm:.2f} [{row.iqm_ci_low:.2f}, "
            f"{row.iqm_ci_high:.2f}] | {row.mean:.2f} [{row.mean_ci_low:.2f}, {row.mean_ci_high:.2f}] | "
            f"{row.reference if isinstance(row.reference, str) else '—'} | {p} |"
        )
    return "\n".join(lines) + "\n"


def write_summary(output: str, references: Mapping[str, str | None], reps: int) -> None:
    """
    Write ``test_summary.csv`` and ``test_summary.md`` from ``test_runs.csv`` in ``output`` (nothing without it).

    :param output: The experiment's results folder
    :param references: Configuration -> the configuration it is compared with
    :param reps: Bootstrap replications
    """
    path = os.path.join(output, RUNS_CSV)
    if not os.path.isfile(path):
        return
    table = summary(pd.read_csv(path), references, reps)
    table.to_csv(os.path.join(output, SUMMARY_CSV), index=False)
    Path(output, "test_summary.md").write_text(markdown(table), encoding="utf-8")

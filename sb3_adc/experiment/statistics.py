"""Statistics of benchmark results with rliable's 95% stratified-bootstrap CIs (``experiment`` extra)."""

from __future__ import annotations

import itertools
import warnings
from collections.abc import Callable
from typing import Any

import numpy as np

from sb3_adc.extras import requires_extra

with requires_extra("experiment", "the benchmark statistics"):
    import pandas as pd
    from rliable import library as rly
    from rliable import metrics

#: Coverage of the confidence intervals.
CONFIDENCE = 0.95
#: Columns of :func:`final_performance`: the IQM and the mean, each with its CI.
FINAL_PERFORMANCE_COLUMNS: tuple[str, ...] = ("env", "algo", "n_runs")
FINAL_PERFORMANCE_COLUMNS += tuple(f"{s}{end}" for s in ("iqm", "mean") for end in ("", "_ci_low", "_ci_high"))
WALLCLOCK_CURVE_COLUMNS = ("env", "algo", "wall_time_s", "n_runs", "mean", "mean_ci_low", "mean_ci_high", "iqm")
#: Columns of :func:`learning_curves`: those of :func:`wallclock_curves` against timesteps, and the variance with its CI.
CURVE_COLUMNS = ("env", "algo", "timesteps", *WALLCLOCK_CURVE_COLUMNS[3:], "variance", "variance_ci_low", "variance_ci_high")
PERFORMANCE_PROFILE_COLUMNS = ("env", "algo", "n_runs", "tau", "fraction", "fraction_ci_low", "fraction_ci_high")
IMPROVEMENT_COLUMNS = ("algo_x", "algo_y", "n_envs", "probability", "ci_low", "ci_high")


def interval_estimates(
    data: dict[str, Any], func: Callable[..., Any], reps: int, seed: int
) -> tuple[dict[str, Any], dict[str, Any]]:
    """
    rliable's point estimates and 95% stratified-bootstrap intervals, reproducible from ``seed``.

    :param data: Name -> a ``(runs, ...)`` matrix of scores, or a tuple of them (the arguments of ``func``)
    :param func: The statistic
    :param reps: Bootstrap replications
    :param seed: Seed of the bootstrap
    :return: Name -> point estimate, and name -> interval (rows: low, high)
    """
    # rliable 1.2 draws its resamples from NumPy's global generator (`random_state` only seeds arch's own):
    # seed it for reproducible intervals, and give it back its state afterwards.
    global_state = np.random.get_state()  # noqa: NPY002
    np.random.seed(seed)  # noqa: NPY002
    try:
        with warnings.catch_warnings():
            # rliable passes `random_state` to arch, which deprecates it.
            warnings.filterwarnings("ignore", category=FutureWarning, module="arch")
            return rly.get_interval_estimates(
                data, func, reps=reps, confidence_interval_size=CONFIDENCE, random_state=np.random.RandomState(seed)
            )
    finally:
        np.random.set_state(global_state)  # noqa: NPY002


# rliable's IQM and probability of improvement call SciPy's `trim_mean` and `mannwhitneyu`, whose NaN-policy wrappers
# cost about a millisecond a call; a bootstrap makes thousands of calls. These two compute the same numbers with NumPy
# alone (tests/experiment/test_experiment_statistics.py checks them against rliable's).
def iqm(scores: np.ndarray, axis: int | None = None) -> Any:
    """
    rliable's IQM (``aggregate_iqm``): the mean of the middle half of the scores, as SciPy's ``trim_mean(scores, 0.25)``.

    :param scores: The scores
    :param axis: The axis it is taken along (``None``: all the scores)
    """
    values, along = (np.ravel(scores), 0) if axis is None else (np.asarray(scores), axis)
    count = values.shape[along]
    cut = int(0.25 * count)
    middle = np.partition(values, (cut, count - cut - 1), axis=along).take(range(cut, count - cut), axis=along)
    return np.mean(middle, axis=along)


def probability_of_improvement_metric(scores_x: np.ndarray, scores_y: np.ndarray) -> float:
    """
    rliable's ``probability_of_improvement``: per task (column), P(X > Y) + P(X = Y) / 2 over all pairs of runs
    (the Mann-Whitney U over ``n_x * n_y``), averaged over the tasks.

    :param scores_x: ``(runs of X, tasks)`` scores
    :param scores_y: ``(runs of Y, tasks)`` scores
    """
    x, y = scores_x[:, None, :], scores_y[None, :, :]
    wins = (x > y).sum(axis=(0, 1)) + 0.5 * (x == y).sum(axis=(0, 1))
    return float(np.mean(wins / (scores_x.shape[0] * scores_y.shape[0])))


def iqm_and_mean(scores: np.ndarray) -> np.ndarray:
    """rliable's IQM and mean of all the scores."""
    return np.array([iqm(scores), metrics.aggregate_mean(scores)])


def _bootstrap(
    scores: np.ndarray | tuple[np.ndarray, ...], func: Callable[..., Any], reps: int, seed: int
) -> tuple[np.ndarray, np.ndarray]:
    """Point and interval (rows: low, high) of ``func(*scores)``, the point twice for fewer than two runs."""
    matrices = scores if isinstance(scores, tuple) else (scores,)
    if min(matrix.shape[0] for matrix in matrices) < 2:
        point = np.asarray(func(*matrices))
        return point, np.stack([point, point])
    points, intervals = interval_estimates({"scores": scores}, func, reps, seed)
    return np.asarray(points["scores"]), np.asarray(intervals["scores"])


def _per_algo(table: pd.DataFrame, columns: tuple[str, ...], make: Callable[[pd.DataFrame], Any]) -> pd.DataFrame:
    """The columns ``make`` gives for the rows of each (env, algo) (``None``: none), one below the other."""
    groups = table.groupby(["env", "algo"], sort=True)
    frames = [pd.DataFrame({"env": env, "algo": algo, **made}) for (env, algo), rows in groups if (made := make(rows))]
    return pd.concat(frames, ignore_index=True)[list(columns)] if frames else pd.DataFrame(columns=list(columns))


def _scores(table: pd.DataFrame) -> np.ndarray:
    return table["mean_return"].to_numpy(dtype=np.float64).reshape(-1, 1)


def final_performance(final: pd.DataFrame, reps: int = 2000, seed: int = 0) -> pd.DataFrame:
    """
    IQM and mean of the final returns of each algorithm on each environment, with 95% stratified-bootstrap CIs.

    :param final: One row per run, with columns ``env``, ``algo`` and ``mean_return`` (``final.csv``)
    :param reps: Bootstrap replications
    :param seed: Seed of the bootstrap
    :return: One row per (env, algo), columns :data:`FINAL_PERFORMANCE_COLUMNS`
    """
    rows = []
    for (env, algo), group in final.groupby(["env", "algo"], sort=True):
        point, interval = _bootstrap(_scores(group), iqm_and_mean, reps, seed)
        rows.append([env, algo, len(group), point[0], *interval[:, 0], point[1], *interval[:, 1]])
    return pd.DataFrame(rows, columns=list(FINAL_PERFORMANCE_COLUMNS))


def last_evaluations(evaluations: pd.DataFrame) -> pd.DataFrame:
    """
    The last periodic evaluation of each run (a stand-in for ``final.csv``).

    :param evaluations: The evaluation curves (``evaluations.csv``)
    """
    ordered = evaluations.sort_values("timesteps", kind="stable")
    return ordered.groupby(["env", "algo", "seed"], sort=True).tail(1).reset_index(drop=True)


def run_matrix(table: pd.DataFrame, column: str, value: str) -> tuple[np.ndarray, np.ndarray]:
    """
    The values of each run (rows, by seed) at each point of ``column`` that every run has.

    :param table: Rows of one (env, algo), with a ``seed`` column
    :param column: The x axis (``timesteps`` or ``episode``)
    :param value: The y values
    :return: The x values and a ``(n_runs, n_points)`` matrix
    """
    pivot = table.pivot_table(index="seed", columns=column, values=value, aggfunc="mean").dropna(axis=1)
    return pivot.columns.to_numpy(), pivot.to_numpy(dtype=np.float64)


def _curve_metrics(scores: np.ndarray) -> np.ndarray:
    """Mean, IQM and (for two runs or more) variance across runs at each point; ``scores``: (runs, 1, points)."""
    per_run = scores[:, 0, :]
    variance = per_run.var(axis=0, ddof=1) if per_run.shape[0] > 1 else np.full(per_run.shape[1], np.nan)
    return np.concatenate([per_run.mean(axis=0), iqm(per_run, axis=0), variance])


def _curve_columns(matrix: np.ndarray, reps: int, seed: int) -> dict[str, Any]:
    """Across the runs (rows of ``matrix``) at each point: ``n_runs``, and the mean, IQM and variance with CIs."""
    point, interval = _bootstrap(matrix[:, None, :], _curve_metrics, reps, seed)
    columns: dict[str, Any] = {"n_runs": matrix.shape[0]}
    for index, name in enumerate(("mean", "iqm", "variance")):  # the blocks of _curve_metrics
        block = slice(index * matrix.shape[1], (index + 1) * matrix.shape[1])
        columns |= {name: point[block], f"{name}_ci_low": interval[0, block], f"{name}_ci_high": interval[1, block]}
    return columns


def learning_curves(evaluations: pd.DataFrame, reps: int = 2000, seed: int = 0) -> pd.DataFrame:
    """
    Per (env, algo), at each timestep every run evaluated: mean return (with CI), IQM and variance (with CI) across runs.

    :param evaluations: The evaluation curves (``evaluations.csv``)
    :param reps: Bootstrap replications
    :param seed: Seed of the bootstrap
    :return: One row per (env, algo, timesteps), columns :data:`CURVE_COLUMNS`
    """

    def curve(group: pd.DataFrame) -> dict[str, Any] | None:
        steps, matrix = run_matrix(group, "timesteps", "mean_return")
        return {"timesteps": steps.astype(np.int64), **_curve_columns(matrix, reps, seed)} if matrix.size else None

    return _per_algo(evaluations, CURVE_COLUMNS, curve)


def evaluation_times(evaluations: pd.DataFrame, episodes: pd.DataFrame) -> pd.DataFrame:
    """
    The evaluations with the seconds their run had trained then (``wall_time_s``), interpolated between the ends
    of the training episodes around them. Runs without episode times are left out.

    :param evaluations: The evaluation curves (``evaluations.csv``)
    :param episodes: The training episodes (``episodes.csv``, with ``wall_time_s``)
    """
    timed = dict(list(episodes.dropna(subset=["wall_time_s"]).groupby(["env", "algo", "seed"])))
    frames = []
    for key, group in evaluations.groupby(["env", "algo", "seed"], sort=True):
        if key in timed:
            run = timed[key].sort_values("timesteps", kind="stable")
            # The run's clock starts at zero steps: evaluations before the first episode's end are interpolated from it.
            steps = np.concatenate([[0.0], run["timesteps"].to_numpy(np.float64)])
            seconds = np.concatenate([[0.0], run["wall_time_s"].to_numpy(np.float64)])
            frames.append(group.assign(wall_time_s=np.interp(group["timesteps"].to_numpy(np.float64), steps, seconds)))
    return pd.concat(frames, ignore_index=True) if frames else evaluations.iloc[:0].assign(wall_time_s=[])


def wallclock_curves(
    evaluations: pd.DataFrame, episodes: pd.DataFrame, n_points: int = 50, reps: int = 2000, seed: int = 0
) -> pd.DataFrame:
    """
    Learning curves against wall-clock time: across the runs of each (env, algo), the mean (with CI) and IQM of
    the latest evaluation return of each run at ``n_points`` times, between the times every run has evaluated.

    :param evaluations: The evaluation curves (``evaluations.csv``)
    :param episodes: The training episodes (``episodes.csv``, with ``wall_time_s``)
    :param n_points: Times per curve (at least 2)
    :param reps: Bootstrap replications
    :param seed: Seed of the bootstrap
    :return: One row per (env, algo, time), columns :data:`WALLCLOCK_CURVE_COLUMNS`
    """
    if n_points < 2:
        raise ValueError(f"n_points must be >= 2, got {n_points}")

    def curve(group: pd.DataFrame) -> dict[str, Any] | None:
        runs = [run.sort_values("wall_time_s") for _, run in group.groupby("seed", sort=True)]
        start = max(float(run["wall_time_s"].iloc[0]) for run in runs)
        stop = min(float(run["wall_time_s"].iloc[-1]) for run in runs)
        if stop <= start:
            return None
        times = np.linspace(start, stop, n_points)
        latest = [np.searchsorted(run["wall_time_s"].to_numpy(np.float64), times, side="right") - 1 for run in runs]
        matrix = np.stack([run["mean_return"].to_numpy(np.float64)[index] for run, index in zip(runs, latest, strict=True)])
        return {"wall_time_s": times, **_curve_columns(matrix, reps, seed)}

    return _per_algo(evaluation_times(evaluations, episodes), WALLCLOCK_CURVE_COLUMNS, curve)


def time_to_threshold(evaluations: pd.DataFrame, episodes: pd.DataFrame, threshold: float) -> pd.DataFrame:
    """
    When each run's evaluation return first stays at or above ``threshold`` until its end: the timestep of that
    evaluation and the training episodes finished by then (``NaN`` where the last evaluation is below it).

    :param evaluations: The evaluation curves (``evaluations.csv``)
    :param episodes: The training episodes (``episodes.csv``), to count episodes
    :param threshold: The evaluation return to stay above
    :return: One row per run: ``env``, ``algo``, ``seed``, ``reached``, ``timesteps``, ``episodes``, and the
        ``budget_timesteps`` and ``budget_episodes`` of its last evaluation
    """
    columns = ("env", "algo", "seed", "reached", "timesteps", "episodes", "budget_timesteps", "budget_episodes")
    ends = {key: run["timesteps"].to_numpy(np.int64) for key, run in episodes.groupby(["env", "algo", "seed"])}
    rows = []
    for (env, algo, seed), run in evaluations.groupby(["env", "algo", "seed"], sort=True):
        run = run.sort_values("timesteps")
        steps = run["timesteps"].to_numpy(np.int64)
        below = np.flatnonzero(run["mean_return"].to_numpy(np.float64) < threshold)
        first = 0 if below.size == 0 else int(below[-1]) + 1
        run_ends = ends.get((env, algo, seed), np.empty(0, np.int64))
        reached = first < len(steps)
        reached_at = (int(steps[first]), int((run_ends <= steps[first]).sum())) if reached else (np.nan, np.nan)
        rows.append([env, algo, seed, reached, *reached_at, int(steps[-1]), int((run_ends <= steps[-1]).sum())])
    return pd.DataFrame(rows, columns=list(columns))


def episode_variance(episodes: pd.DataFrame, window: int = 10) -> pd.DataFrame:
    """
    Across-run variance of the training-episode returns at each episode index, and its moving average.

    :param episodes: The training episodes (``episodes.csv``)
    :param window: Episodes of the moving average
    :return: Columns ``env``, ``algo``, ``episode``, ``n_runs``, ``variance``, ``variance_smoothed``
    """

    def variance(group: pd.DataFrame) -> dict[str, Any] | None:
        index, matrix = run_matrix(group, "episode", "return")
        if matrix.shape[0] < 2 or matrix.shape[1] == 0:
            return None
        variance = matrix.var(axis=0, ddof=1)
        smoothed = pd.Series(variance).rolling(window, min_periods=1).mean().to_numpy()
        return dict(episode=index.astype(np.int64), n_runs=len(matrix), variance=variance, variance_smoothed=smoothed)

    return _per_algo(episodes, ("env", "algo", "episode", "n_runs", "variance", "variance_smoothed"), variance)


def performance_profiles(final: pd.DataFrame, n_taus: int = 101, reps: int = 2000, seed: int = 0) -> pd.DataFrame:
    """
    rliable's performance profiles: per (env, algo), the fraction of runs whose final return exceeds each tau, with CIs.

    :param final: One row per run, with columns ``env``, ``algo`` and ``mean_return``
    :param n_taus: Thresholds per environment, spanning its final returns (at least 2)
    :param reps: Bootstrap replications
    :param seed: Seed of the bootstrap
    :return: One row per (env, algo, tau), columns :data:`PERFORMANCE_PROFILE_COLUMNS`
    """
    if n_taus < 2:
        raise ValueError(f"n_taus must be >= 2, got {n_taus}")
    taus = {env: np.linspace(returns.min(), returns.max(), n_taus) for env, returns in final.groupby("env")["mean_return"]}
    for env_taus in taus.values():
        env_taus[0] -= max(1e-6, 1e-6 * abs(env_taus[0]))  # just below the lowest return: every profile starts at 1

    def profile(group: pd.DataFrame) -> dict[str, Any]:
        env_taus = taus[group["env"].iloc[0]]
        # rliable's create_performance_profile, with its profile function: the fraction of runs above each tau.
        fraction, (low, high) = _bootstrap(_scores(group), lambda s: rly.score_distributions(s, env_taus), reps, seed)
        return {"n_runs": len(group), "tau": env_taus, "fraction": fraction, "fraction_ci_low": low, "fraction_ci_high": high}

    return _per_algo(final, PERFORMANCE_PROFILE_COLUMNS, profile)


def probability_of_improvement(final: pd.DataFrame, reps: int = 2000, seed: int = 0) -> pd.DataFrame:
    """
    Probability of improvement (rliable): for each pair of algorithms, P(X > Y) that a run of X ends above a run
    of Y (ties count one half), averaged over the environments both ran, with CI. Each pair appears once, with
    ``adc`` as X where it is in the pair.

    :param final: One row per run, with columns ``env``, ``algo``, ``seed`` and ``mean_return``
    :param reps: Bootstrap replications
    :param seed: Seed of the bootstrap
    :return: One row per pair, columns :data:`IMPROVEMENT_COLUMNS`
    """
    final = final.sort_values("seed", kind="stable") if "seed" in final.columns else final
    envs = [dict(list(table.groupby("algo")["mean_return"])) for _, table in final.groupby("env", sort=True)]
    rows = []
    for pair in itertools.combinations(sorted(final["algo"].unique(), key=lambda algo: (algo != "adc", algo)), 2):
        scores = [[runs[algo].to_numpy(dtype=np.float64) for algo in pair] for runs in envs if set(pair) <= runs.keys()]
        if scores:
            # rliable wants (runs, tasks) matrices: as many runs in every environment, so the shortest count is kept.
            counts = np.min([[len(runs) for runs in env] for env in scores], axis=0)
            x, y = (np.stack([env[i][:count] for env in scores], axis=1) for i, count in enumerate(counts))
            point, interval = _bootstrap((x, y), probability_of_improvement_metric, reps, seed)
            rows.append([*pair, len(scores), float(point), *(float(bound) for bound in interval.ravel())])
    return pd.DataFrame(rows, columns=list(IMPROVEMENT_COLUMNS))


def markdown_table(performance: pd.DataFrame) -> str:
    """
    The final-performance table as Markdown: IQM and mean with their 95% CIs.

    :param performance: The output of :func:`final_performance`
    """
    lines = ["| Environment | Algorithm | Runs | IQM [95% CI] | Mean [95% CI] |", "|---|---|---:|---:|---:|"]
    for row in performance.itertuples(index=False):
        lines.append(
            f"| {row.env} | {row.algo} | {row.n_runs} "
            f"| {row.iqm:.1f} [{row.iqm_ci_low:.1f}, {row.iqm_ci_high:.1f}] "
            f"| {row.mean:.1f} [{row.mean_ci_low:.1f}, {row.mean_ci_high:.1f}] |"
        )
    return "\n".join(lines) + "\n"

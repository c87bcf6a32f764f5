"""The scoring of ``benchmarks/procedural_generalisation.py`` and ``benchmarks/budget_sweep.py`` on a real run: it
loads the model it is asked for (final, best or a checkpoint file), evaluates without the training-only start
jitter and reports one row per test set."""

from __future__ import annotations

import dataclasses
import importlib
import json
import shutil
import sys
import textwrap
from collections import Counter
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
import torch as th
from stable_baselines3 import TD3

from sb3_adc.cli import main
from sb3_adc.experiment import TrainSettings
from sb3_adc.experiment.benchmark import BenchmarkSettings, RunSpec, run_benchmark
from sb3_adc.experiment.callbacks import EvaluationHistory
from sb3_adc.experiment.layout import RunLayout
from sb3_adc_envs.lidar_course import LidarObstacleCourseEnv
from sb3_adc_envs.lidar_course.course import course_from_dict

ROOT = Path(__file__).resolve().parents[2]
ENV_ID = "sb3_adc/LidarObstacleCourse-v1"
TINY_TD3 = """
    sb3_adc/LidarObstacleCourse-v1:
      n_timesteps: 300
      policy: MlpPolicy
      learning_starts: 100
      batch_size: 16
      buffer_size: 1000
      policy_kwargs: "dict(net_arch=[8])"
      env_kwargs: {max_episode_steps: 40, start_position_jitter: 0.2, start_heading_jitter_deg: 15.0}
    """


@pytest.fixture(scope="module")
def scripts():
    sys.path.insert(0, str(ROOT / "benchmarks"))
    try:
        yield importlib.import_module("procedural_generalisation"), importlib.import_module("budget_sweep")
    finally:
        sys.path.remove(str(ROOT / "benchmarks"))
        sys.modules.pop("budget_sweep", None)
        sys.modules.pop("procedural_generalisation", None)


def train_tiny_run(folder: Path, algo: str, entry: str, *extra: str) -> str:
    """Train one seed-3 run of ``algo`` with the hyperparameter ``entry`` through the CLI; its run folder."""
    conf = folder / f"{algo}.yml"
    conf.write_text(textwrap.dedent(entry))
    args = ["train", "--algo", algo, "--env", ENV_ID, "-conf", str(conf), "-f", str(folder / "logs"), "--seed", "3"]
    assert main([*args, *extra, "--final-eval-episodes", "1", "--no-progress-bar"]) == 0
    (run,) = (folder / "logs" / algo).iterdir()
    return str(run)


@pytest.fixture(scope="module")
def run_dir(tmp_path_factory) -> str:
    extra = ["--eval-freq", "100", "--eval-episodes", "1", "--save-freq", "100"]
    return train_tiny_run(tmp_path_factory.mktemp("scoring"), "td3", TINY_TD3, *extra)


def same_parameters(model, path: str) -> bool:
    saved = TD3.load(path, device="cpu").policy.state_dict()
    return all(th.equal(value, saved[key]) for key, value in model.policy.state_dict().items())


def test_scoring_loads_the_model_asked_for_without_training_jitter(scripts, run_dir):
    procedural, _ = scripts
    layout = RunLayout(run_dir, ENV_ID)
    checkpoint = layout.checkpoints()[0].model
    for which, path in [("final", layout.final_model), ("best", layout.best_model)]:
        settings, _, model, kwargs = procedural.load_for_scoring(run_dir, which)
        assert same_parameters(model, path)
        assert (settings.algo, settings.env_id) == ("td3", ENV_ID)
        assert kwargs == {"max_episode_steps": 40}
    _, _, model, _ = procedural.load_for_scoring(run_dir, "final", path=checkpoint)
    assert same_parameters(model, checkpoint)
    # The three files differ, so the comparisons above tell them apart.
    assert not same_parameters(model, layout.final_model)
    assert not same_parameters(model, layout.best_model)
    assert not same_parameters(TD3.load(layout.best_model, device="cpu"), layout.final_model)
    with pytest.raises(ValueError, match="`which` must be one of"):
        procedural.load_for_scoring(run_dir, "newest")


def test_score_run_reports_each_test_set_of_the_run(scripts, run_dir):
    procedural, _ = scripts
    rows, paths = procedural.score_run(run_dir, "td3", ENV_ID, 3, [], 1, n_layouts=2, trajectory_layouts=1, which="best")
    assert [(row["algo"], row["seed"], row["episodes"]) for row in rows] == [("td3", 3, 2)]
    assert 0.0 <= rows[0]["success_rate"] <= 1.0
    assert len(paths) == 1
    assert set(paths[0]["seed"]) == {3}
    # The progress line printed as each run is scored names the run and its rate on each test set.
    line = procedural.scored_line("td3", 3, [*rows, {"test_set": "unseen_posts", "success_rate": 0.25}])
    assert line == f"td3 seed 3: held-out layouts {rows[0]['success_rate']:.2f}, unseen_posts 0.25"


def test_budget_sweep_scores_a_checkpoint_and_names_configs_files(scripts, run_dir, tmp_path):
    procedural, budget_sweep = scripts
    point = RunLayout(run_dir, ENV_ID).checkpoints()[0]
    (row,) = budget_sweep.score_checkpoint(run_dir, "tiny", 3, point.timesteps, point.model, 2)
    assert (row["config"], row["algo"], row["timesteps"], row["episodes"]) == ("tiny", "td3", point.timesteps, 2)
    # The progress line printed as each checkpoint is scored names the run, the checkpoint and its rate.
    line = budget_sweep.checkpoint_line([row, {**row, "config": "tiny (actor itself)", "success_rate": 0.25}])
    assert line == f"seed 3 at {point.timesteps} steps: tiny {row['success_rate']:.2f}, tiny (actor itself) 0.25"
    inside = ROOT / "benchmarks" / "configs" / "budget_sweep" / "shaping.yml"
    assert procedural.repository_path(str(inside)) == "benchmarks/configs/budget_sweep/shaping.yml"
    outside = tmp_path / "configs.yml"
    assert procedural.repository_path(str(outside)) == str(outside.resolve())


def sweep_rows(config: str, successes_by_checkpoint: dict[int, list[int]], episodes: int = 50) -> list[dict]:
    """``sweep.csv`` rows of one configuration: per checkpoint, one run per entry of its successes."""
    return [
        {"config": config, "seed": seed, "timesteps": steps, "episodes": episodes, "successes": hits,
         "success_rate": hits / episodes}
        for steps, successes in successes_by_checkpoint.items()
        for seed, hits in enumerate(successes)
    ]  # fmt: skip


def test_the_sweep_rule_chooses_the_best_mean_at_the_last_checkpoint_as_deployed(scripts):
    _, budget_sweep = scripts
    configs = {"one-step": {"gamma": 0.98}, "3-step": {"gamma": 0.98, "n_steps": 3}}
    rows = [
        # Ahead earlier in training, behind at the last checkpoint.
        *sweep_rows("one-step", {15_000: [50, 50], 150_000: [45, 44]}),
        *sweep_rows("3-step", {15_000: [10, 10], 150_000: [46, 44]}),
        # An actor itself that would win is not a deployed policy.
        *sweep_rows("one-step (actor itself)", {15_000: [0, 0], 150_000: [50, 50]}),
    ]
    assert budget_sweep.winner(pd.DataFrame(rows), configs) == "3-step"
    behind = [row for row in rows if not (row["config"] == "3-step" and row["timesteps"] == 150_000)]
    behind += sweep_rows("3-step", {150_000: [44, 44]})
    assert budget_sweep.winner(pd.DataFrame(behind), configs) == "one-step"
    # An exact tie (89 of 100 each, in other splits between the runs) goes to the longer returns, in either order.
    tie = [row for row in behind if not (row["config"] == "3-step" and row["timesteps"] == 150_000)]
    tie += sweep_rows("3-step", {150_000: [43, 46]})
    assert budget_sweep.winner(pd.DataFrame(tie), configs) == "3-step"
    assert budget_sweep.winner(pd.DataFrame(tie), dict(reversed(configs.items()))) == "3-step"
    with pytest.raises(ValueError, match=r"no final checkpoint of \['4 rays'\]"):
        budget_sweep.winner(pd.DataFrame(tie), {**configs, "4 rays": {}})


@pytest.fixture(scope="module")
def averaged_run_dir(tmp_path_factory) -> str:
    """A tiny ADC run whose model deploys an averaged actor."""
    entry = TINY_TD3.replace("net_arch=[8])", "net_arch=[8], n_intervals=4, actor_average_tau=0.5)")
    return train_tiny_run(tmp_path_factory.mktemp("averaged"), "adc", entry, "--eval-freq", "-1", "--save-freq", "300")


def test_budget_sweep_scores_an_averaged_actor_as_deployed_and_as_the_actor_itself(scripts, averaged_run_dir, monkeypatch):
    _, budget_sweep = scripts
    point = RunLayout(averaged_run_dir, ENV_ID).checkpoints()[-1]
    averaged: list[bool] = []

    def layout_success(model, env, layout_seed):
        averaged.append(model.policy.actor_average is not None)
        return layout_seed % 2 == 0

    monkeypatch.setattr(budget_sweep, "layout_success", layout_success)
    rows = budget_sweep.score_checkpoint(averaged_run_dir, "tiny", 3, point.timesteps, point.model, 2)
    assert [row["config"] for row in rows] == ["tiny", "tiny (actor itself)"]
    assert [row["successes"] for row in rows] == [1, 1]
    # The deployed policy's two layouts with the average, then the same two with the actor itself.
    assert averaged == [True, True, False, False]


@pytest.mark.parametrize("actor_itself", [False, True])
def test_score_run_scores_the_actor_itself_when_asked(scripts, averaged_run_dir, monkeypatch, actor_itself):
    procedural, _ = scripts
    averaged: list[bool] = []

    def score_policy(model, *args):
        averaged.append(model.policy.actor_average is not None)
        return [{"test_set": "held-out layouts", "success_rate": 1.0}], []

    monkeypatch.setattr(procedural, "score_policy", score_policy)
    rows, _ = procedural.score_run(averaged_run_dir, "adc", ENV_ID, 3, [], 1, 2, 0, actor_itself=actor_itself)
    assert averaged == [not actor_itself]
    assert rows == [{"algo": "adc", "env": ENV_ID, "seed": 3, "test_set": "held-out layouts", "success_rate": 1.0}]


def test_score_run_refuses_the_actor_itself_of_a_model_without_an_average(scripts, run_dir):
    procedural, _ = scripts
    with pytest.raises(SystemExit, match="does not deploy an averaged actor"):
        procedural.score_run(run_dir, "td3", ENV_ID, 3, [], 1, 2, 0, actor_itself=True)


# A 14 m x 8 m rectangular loop 2 m wide; the robot starts at (3, 0) heading +x along the bottom straight.
LOOP = {
    "name": "loop",
    "corridor": {"width": 2.0, "centerline": [[0, 0], [14, 0], [14, 8], [0, 8]], "corner_radius": 1.6},
    "start": {"x": 3.0, "y": 0.0, "heading_deg": 0.0},
}


class Straight:
    """A policy that never steers: on a curving course it ends against something."""

    def predict(self, observation, deterministic=True):
        return np.zeros(1, dtype=np.float32), None


def test_scoring_counts_what_each_failed_episode_hit(scripts):
    procedural, _ = scripts
    rows, _ = procedural.score_policy(Straight(), lambda env: env, ENV_ID, {}, ["unseen_posts"], 2, 3, 0)
    held_out, _ = rows
    for row in rows:
        failures = row["episodes"] - row["successes"]
        hits = [row[f"hit_{kind}"] for kind in procedural.HITS]
        # Every failure ended touching something; no kind is counted more often than there were failures.
        assert sum(hits) >= failures > 0
        assert max(hits) <= failures
        assert row["hit_unseen"] <= row["hit_obstacle"] <= failures
        assert row["hit_obstacle"] >= max(row["hit_box"], row["hit_cylinder"], row["hit_stub"])
    assert held_out["hit_wall"] >= 1
    # Straight ahead of the start: a post (6 cm radius) on a straight, then a box across the corridor's middle,
    # both in ray 0's line from the start, 3 m before them: seen in time.
    for obstacle, hit in [
        ({"shape": "cylinder", "position": [6, 0], "radius": 0.06}, ["cylinder"]),
        ({"shape": "box", "position": [6, 0], "size": [0.3, 0.3]}, ["box"]),
    ]:
        course = course_from_dict({**LOOP, "obstacles": [obstacle]})
        env = LidarObstacleCourseEnv(course=course)
        assert procedural.episode_outcome(Straight(), env) == (False, hit, False)
        env.close()
    # Without an obstacle the robot ends against the corridor's wall: no obstacle to have seen.
    env = LidarObstacleCourseEnv(course=course_from_dict(LOOP))
    assert procedural.episode_outcome(Straight(), env) == (False, ["wall"], False)
    env.close()


@pytest.mark.parametrize(
    ("offset", "radius", "n_rays", "unseen"),
    [
        # A 5 cm post 12 cm beside the robot's straight line, touching its side: the 8 rays' first diagonal steps past
        # it between two scans (no ray meets it before the contact), the 24 rays' first meets it 5 steps before:
        # too late either way.
        (0.12, 0.05, 8, True),
        (0.12, 0.05, 24, True),
        # A 2 cm post 16 cm beside it: the 24 rays meet it 6 steps before the contact, just in time.
        (0.16, 0.02, 24, False),
    ],
)
def test_an_obstacle_is_unseen_when_no_ray_meets_it_while_it_can_be_avoided(scripts, offset, radius, n_rays, unseen):
    procedural, _ = scripts
    post = {"shape": "cylinder", "position": [6, offset], "radius": radius}
    env = LidarObstacleCourseEnv(course=course_from_dict({**LOOP, "obstacles": [post]}), n_rays=n_rays)
    assert procedural.episode_outcome(Straight(), env) == (False, ["cylinder"], unseen)
    # The same episode step by step: the scans before the contact in which a ray met the post.
    post_id = env.simulation.obstacle_ids[0]
    env.reset()
    sightings = []
    for step in range(1, 40):
        _, _, terminated, _, _ = env.step(np.zeros(1, dtype=np.float32))
        if terminated:
            break
        if post_id in env.simulation.ray_bodies:
            sightings.append(step)
    before = [step - sighting for sighting in sightings]
    late, early = procedural.SIGHTING
    assert unseen == (not any(late <= steps <= early for steps in before))
    assert (n_rays == 8) == (not before)
    env.close()


def test_the_training_record_follows_the_invocations_that_trained(scripts, tmp_path):
    procedural, _ = scripts
    metadata = tmp_path / "metadata.json"
    # Metadata of the former layout: one invocation, its run counts as runs_this_invocation.
    older = {"training_wall_time_s": 1078.3, "workers": 2, "runs_this_invocation": {"resumed": 2, "trained": 4}}
    metadata.write_text(json.dumps(older))
    first = {"wall_time_s": 1078.3, "workers": 2, "runs": {"resumed": 2, "trained": 4}}
    # Scoring only: the earlier record stays.
    scored = procedural.training_record(tmp_path, Counter(skipped=6), 3.0, 1)
    assert scored == {"training_wall_time_s": 1078.3, "training_workers": 2, "training_invocations": [first]}
    # Training more runs beside finished ones (an algorithm added): added to the record.
    metadata.write_text(json.dumps(scored))
    added = procedural.training_record(tmp_path, Counter(trained=10, skipped=10), 500.04, 2)
    second = {"wall_time_s": 500.0, "workers": 2, "runs": {"skipped": 10, "trained": 10}}
    assert added == {"training_wall_time_s": 1578.3, "training_workers": 2, "training_invocations": [first, second]}
    # The same invocation writing its results again (its metadata holds it now): counted from the record it found.
    metadata.write_text(json.dumps(added))
    assert procedural.training_record(tmp_path, Counter(trained=10, skipped=10), 500.04, 2, earlier=scored) == added
    # Training every run anew: a new record.
    anew = procedural.training_record(tmp_path, Counter(trained=20), 7.0, 1)
    assert anew == {
        "training_wall_time_s": 7.0,
        "training_workers": 1,
        "training_invocations": [{"wall_time_s": 7.0, "workers": 1, "runs": {"trained": 20}}],
    }
    # --algos: a grid trained by one invocation per algorithm keeps each one's record; training an algorithm anew
    # replaces only that algorithm's invocations.
    metadata.write_text(json.dumps({"algos": ["td3"], **anew}))
    ddpg = procedural.training_record(tmp_path, Counter(trained=10), 30.0, 2, ["ddpg"])
    ddpg_entry = {"wall_time_s": 30.0, "workers": 2, "algos": ["ddpg"], "runs": {"trained": 10}}
    td3_entry = {**anew["training_invocations"][0], "algos": ["td3"]}  # an older entry takes the metadata's algos
    assert ddpg["training_invocations"] == [td3_entry, ddpg_entry]
    assert ddpg["training_wall_time_s"] == 37.0
    metadata.write_text(json.dumps({"algos": ["ddpg"], **ddpg}))
    again = procedural.training_record(tmp_path, Counter(trained=10), 40.0, 2, ["ddpg"])
    assert again["training_invocations"] == [td3_entry, {**ddpg_entry, "wall_time_s": 40.0}]
    both = procedural.training_record(tmp_path, Counter(trained=20), 50.0, 2, ["td3", "ddpg"])
    assert both["training_invocations"] == [
        {"wall_time_s": 50.0, "workers": 2, "algos": ["td3", "ddpg"], "runs": {"trained": 20}}
    ]
    # No metadata yet: this invocation.
    metadata.unlink()
    assert procedural.training_record(tmp_path, Counter(skipped=3), 2.0, 1)["training_invocations"] == [
        {"wall_time_s": 2.0, "workers": 1, "runs": {"skipped": 3}}
    ]


def test_the_engines_record_of_invocations_is_the_training_record(scripts, tmp_path):
    """With ``invocations.json`` in the grid's run folders, every invocation that trained or resumed runs, or was
    cut short, is on record, from any invocation (scoring-only ones included); older metadata entries stay only
    when the first recorded invocation found runs made before it."""
    from sb3_adc.experiment.invocations import InvocationJournal

    procedural, _ = scripts
    output, runs = tmp_path / "results", tmp_path / "runs"
    output.mkdir()
    legacy = {"wall_time_s": 900.0, "workers": 2, "runs": {"trained": 2}}
    (output / "metadata.json").write_text(json.dumps({"training_invocations": [legacy]}))
    now = [0.0]

    def invocation(folder, statuses, seconds, finished=True):
        journal = InvocationJournal([(str(runs / folder), [folder], 5)], 2, "local", clock=lambda: now[0])
        try:
            with journal:
                for status in statuses:
                    journal.record(str(runs / folder), status)
                now[0] += seconds
                if not finished:
                    raise KeyboardInterrupt
        except KeyboardInterrupt:
            pass
        now[0] += 1000.0  # between invocations

    invocation("td3", ["resumed", "trained"], 0.0, finished=False)  # killed: its time is the last heartbeat's
    invocation("td3", ["skipped", "skipped", "trained", "trained", "trained"], 1200.0)
    invocation("ddpg", ["trained"] * 5, 600.0)
    invocation("td3", ["skipped"] * 5, 5.0)  # scoring only
    record = procedural.training_record(output, Counter(skipped=5), 5.0, 1, ["td3"], runs)
    entries = record["training_invocations"]
    assert entries[0] == legacy  # the first recorded invocation resumed runs made before the record
    assert [entry["finished"] for entry in entries[1:]] == [False, True, True]
    assert [entry["algos"] for entry in entries[1:]] == [["td3"], ["td3"], ["ddpg"]]
    assert [entry["wall_time_s"] for entry in entries[1:]] == [0.0, 1200.0, 600.0]
    assert record["training_wall_time_s"] == 2700.0
    assert record["training_workers"] == 2
    # Runs trained from scratch by the first recorded invocation: the older entries describe other runs.
    for path in runs.glob("*/invocations.json"):
        path.unlink()
    invocation("td3", ["trained"] * 5, 50.0)
    assert procedural.training_record(output, Counter(trained=5), 50.0, 2, ["td3"], runs)["training_invocations"] == [
        {key: value for key, value in entry.items() if key not in ("id", "backend", "runs_in_grid")}
        for entry in json.loads((runs / "td3" / "invocations.json").read_text())
    ]


def test_validated_runs_keep_the_model_of_the_best_validation_success(scripts, tmp_path):
    """``--validation``: runs of their own whose periodic evaluations are on validation layouts, by success."""
    procedural, _ = scripts
    assert procedural.periodic_evaluations(False, 300) == {"eval_episodes": 5}
    (tmp_path / "conf").mkdir()
    (tmp_path / "conf" / "td3.yml").write_text(textwrap.dedent(TINY_TD3))
    settings = BenchmarkSettings(
        algos=["td3"],
        env_ids=[ENV_ID],
        seeds=[3],
        log_folder=str(tmp_path / "runs"),
        conf_folder=str(tmp_path / "conf"),
        final_eval_episodes=1,
        **procedural.periodic_evaluations(True, 300, validation_episodes=2),
    )
    result = run_benchmark(settings, workers=1)
    assert not result.failures
    run_dir = RunSpec("td3", ENV_ID, 3).run_dir(settings.log_folder)
    history = EvaluationHistory.load(str(Path(run_dir) / "evaluations.npz"))
    assert history.timesteps == list(range(30, 301, 30))
    assert [len(row) for row in history.successes] == [2] * procedural.VALIDATION_EVALUATIONS
    # validation.csv: each evaluation's success rate on the validation episodes, as the run recorded it.
    table = procedural.validation_table(pd.read_csv(result.tables["evaluations.csv"]))
    assert list(table["timesteps"]) == history.timesteps
    assert list(table["success_rate"]) == history.success_rates()
    assert (table["n_episodes"] == 2).all()
    saved = TrainSettings.of_run(run_dir)
    assert saved.best_model_metric == "success"
    assert saved.eval_env_kwargs == {"layout_seeds": [2_000_000, 2_000_100]}
    assert Path(RunLayout(run_dir, ENV_ID).best_model).is_file()


def _scored_run(algo: str, seed: int, rate: float) -> tuple[dict, list[dict], list[pd.DataFrame]]:
    """A scored run as ``score_run`` and the engine give it: its final row, its scores and its paths."""
    final = {"algo": algo, "env": ENV_ID, "seed": seed, "timesteps": 300, "mean_return": 0.1 + 0.2 * rate, "n_episodes": 1}
    rows = [{"algo": algo, "env": ENV_ID, "seed": seed, "test_set": name, "success_rate": rate} for name in ("a", "b")]
    paths = [pd.DataFrame({"algo": algo, "seed": seed, "course": "layout 1", "step": [0, 1], "x": [0.0, 0.1]})]
    return final, rows, paths


def test_scored_runs_are_kept_with_the_results_and_pending_until_every_seed_is(scripts, tmp_path, monkeypatch):
    """A grid spread over machines: each scored run is written at once, the runs of an algorithm with seeds still
    to score apart (``pending/``, out of the statistics' tables); a later invocation without the run folders keeps
    them, as long as the algorithm's entry and the scoring protocol are those it scored with."""
    procedural, _ = scripts
    protocol = dict.fromkeys(procedural.PROTOCOL, "same")
    entries = {"td3": {"gamma": 0.98}, "sac": {"gamma": 0.99}}

    def ledger(entries=entries, protocol=protocol, rescore=False):
        return procedural.ScoredRuns(tmp_path, protocol, entries, [0, 1], rescore)

    scored = ledger()
    scored.metadata = {**protocol, "n_timesteps": "each entry's n_timesteps"}
    for algo, seed in (("td3", 0), ("sac", 0), ("td3", 1)):
        scored.add(*_scored_run(algo, seed, 0.5))
    assert scored.complete() == ["td3"]
    assert scored.pending() == {"sac": [0]}
    success = pd.read_csv(tmp_path / "success.csv")
    assert list(zip(success["algo"], success["seed"], strict=True)) == [("td3", 0), ("td3", 0), ("td3", 1), ("td3", 1)]
    assert set(pd.read_csv(tmp_path / "pending" / "final.csv")["algo"]) == {"sac"}
    metadata = json.loads((tmp_path / "metadata.json").read_text())
    assert metadata["pending_runs"] == {"sac": [0]}
    assert list(metadata["entries"]) == ["td3", "sac"]
    # Another machine: the same grid keeps the three runs and trains sac's seed 1 only.
    again = ledger()
    assert again.kept == 3
    assert again.missing("td3") == []
    assert again.missing("sac") == [1]
    again.add(*_scored_run("sac", 1, 1.0))
    assert not (tmp_path / "pending").exists()
    assert "pending_runs" not in again.metadata
    final = (tmp_path / "final.csv").read_bytes()
    assert list(pd.read_csv(tmp_path / "final.csv")["algo"]) == ["td3", "td3", "sac", "sac"]
    # Written again unchanged: the same bytes (floats read back exactly, gzip without a timestamp).
    trajectories = (tmp_path / "trajectories.csv.gz").read_bytes()
    ledger().write()
    assert (tmp_path / "final.csv").read_bytes() == final
    assert (tmp_path / "trajectories.csv.gz").read_bytes() == trajectories
    # An entry changed since: that algorithm's runs are trained and scored again, the others' kept.
    changed = ledger({**entries, "sac": {"gamma": 0.9}})
    assert changed.missing("sac") == [0, 1]
    assert changed.missing("td3") == []
    assert changed.kept == 2
    # An algorithm this invocation does not train is kept while its recorded entry is current (stale_entries).
    monkeypatch.setattr(procedural, "stale_entries", lambda metadata, algos=None: ["sac"])
    assert ledger({"td3": entries["td3"]}).entries == {"td3": entries["td3"]}
    monkeypatch.setattr(procedural, "stale_entries", lambda metadata, algos=None: [])
    assert ledger({"td3": entries["td3"]}).kept == 4
    # Another protocol (another model scored, other test sets) or --rescore: no run is kept.
    assert ledger(protocol={**protocol, "courses": ["other"]}).kept == 0
    assert ledger(rescore=True).kept == 0


def test_a_grid_whose_run_folders_are_gone_keeps_its_scored_runs(script_main, tmp_path):
    """End to end: the runs' folders are lost (another machine); the grid's command trains and scores nothing again
    and writes the same tables."""
    from sb3_adc.experiment.benchmark import run_benchmark as engine

    argv = ["--quick", "--algos", "td3", "--workers", "1", "--reps", "50"]
    script_main("procedural_generalisation", "run_benchmark", engine, argv).main()
    output = tmp_path / "results" / "LidarObstacleCourse-v1_quick"
    tables = {name: (output / name).read_bytes() for name in ("success.csv", "final.csv", "success_rates.csv")}
    assert len(pd.read_csv(output / "final.csv")) == 2
    shutil.rmtree(tmp_path / "runs")

    def no_training(*args, **kwargs):
        raise AssertionError("a kept run was trained again")

    script_main("procedural_generalisation", "run_benchmark", no_training, argv).main()
    assert {name: (output / name).read_bytes() for name in tables} == tables
    assert json.loads((output / "metadata.json").read_text())["runs_this_invocation"] == {"kept": 2}


def test_an_algorithms_statistics_are_written_when_its_last_run_is_scored(script_main, tmp_path):
    """A grid stopped while its next algorithm trains (Ctrl-C, a lost machine): the algorithm whose every run was
    scored before has its statistics, figures and training record in the results folder, beside its runs."""
    from sb3_adc.experiment.benchmark import run_benchmark as engine

    def stopped_at_ddpg(settings, **kwargs):
        if settings.algos == ["ddpg"]:
            raise KeyboardInterrupt
        return engine(settings, **kwargs)

    argv = ["--quick", "--algos", "td3", "ddpg", "--workers", "1", "--reps", "50"]
    with pytest.raises(KeyboardInterrupt):
        script_main("procedural_generalisation", "run_benchmark", stopped_at_ddpg, argv).main()
    output = tmp_path / "results" / "LidarObstacleCourse-v1_quick"
    metadata = json.loads((output / "metadata.json").read_text())
    assert metadata["algos"] == ["td3"]
    assert [entry["algos"] for entry in metadata["training_invocations"]] == [["td3"]]
    assert metadata["runs_this_invocation"] == {"trained": 2}
    rates = pd.read_csv(output / "success_rates.csv")
    assert set(rates["algo"]) == {"td3"}
    assert set(rates["n_runs"]) == {2}
    assert (output / "probability_of_improvement.csv").exists()
    assert (output / "success_rates.png").exists()
    assert (output / "trajectories.png").exists()
    assert (output / "success_rates.md").read_text().count("| td3 | 2 |") == len(rates)


def test_a_run_kept_before_its_machine_is_lost_keeps_the_training_that_made_it(script_main, tmp_path):
    """End to end: a grid stopped after scoring the first of an algorithm's runs (kept as a pending run), whose run
    folders, and with them the engine's journal of invocations, are then lost with the machine. The next invocation
    trains the other run; the training record holds both invocations, the lost one as the pending run recorded it."""
    from sb3_adc.experiment.benchmark import run_benchmark as engine

    def first_seed_then_stopped(settings, **kwargs):
        engine(dataclasses.replace(settings, seeds=settings.seeds[:1]), **kwargs)
        raise KeyboardInterrupt

    argv = ["--quick", "--algos", "td3", "--workers", "1", "--reps", "50"]
    with pytest.raises(KeyboardInterrupt):
        script_main("procedural_generalisation", "run_benchmark", first_seed_then_stopped, argv).main()
    output = tmp_path / "results" / "LidarObstacleCourse-v1_quick"
    metadata = json.loads((output / "metadata.json").read_text())
    assert metadata["pending_runs"] == {"td3": [1000]}
    (lost,) = metadata["training_invocations"]
    assert (lost["algos"], lost["runs"]["trained"]) == (["td3"], 1)
    assert lost["wall_time_s"] > 0
    shutil.rmtree(tmp_path / "runs")

    script_main("procedural_generalisation", "run_benchmark", engine, argv).main()
    metadata = json.loads((output / "metadata.json").read_text())
    assert "pending_runs" not in metadata
    first, second = metadata["training_invocations"]
    assert first == lost
    assert (second["algos"], second["runs"]["trained"], second["finished"]) == (["td3"], 1, True)
    assert metadata["training_wall_time_s"] == pytest.approx(first["wall_time_s"] + second["wall_time_s"], abs=0.1)


def test_the_training_record_keeps_the_invocations_of_kept_runs_trained_elsewhere(scripts, tmp_path):
    """Runs kept from the results (:class:`ScoredRuns`) were trained by invocations whose record went with their
    machine: ``metadata.json`` holds them, and they stay beside the invocations recorded here."""
    from sb3_adc.experiment.invocations import InvocationJournal

    procedural, _ = scripts
    output, runs = tmp_path / "results", tmp_path / "runs"
    output.mkdir()
    elsewhere = {"started": "2026-01-01T00:00:00+00:00", "wall_time_s": 900.0, "workers": 2, "algos": ["td3"]}
    (output / "metadata.json").write_text(json.dumps({"training_invocations": [elsewhere]}))
    with InvocationJournal([(str(runs / "sac"), ["sac"], 2)], 2, "local") as journal:
        journal.record(str(runs / "sac"), "trained")
    record = procedural.training_record(output, Counter(trained=1), 5.0, 2, ["sac"], runs, kept=True)
    assert record["training_invocations"][0] == elsewhere
    assert record["training_invocations"][1]["algos"] == ["sac"]
    # Without kept runs, runs trained from scratch here: the earlier entries describe other runs.
    alone = procedural.training_record(output, Counter(trained=1), 5.0, 2, ["sac"], runs)
    assert [entry["algos"] for entry in alone["training_invocations"]] == [["sac"]]

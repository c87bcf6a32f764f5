"""``sb3-adc enjoy``: play a trained model, print its returns, optionally record a GIF or a video."""

from __future__ import annotations

import argparse
import os

import numpy as np

from sb3_adc.cli.common import (
    CommandError,
    add_runtime_arguments,
    apply_runtime_arguments,
    check_positive,
    refusing_unsafe_files,
)
from sb3_adc.config import ALGORITHMS
from sb3_adc.experiment.enjoy import MODEL_CHOICES, load_model, load_run, model_path, play, write_recording
from sb3_adc.experiment.layout import env_name, latest_run_dir
from sb3_adc.experiment.settings import EVAL_SEED_OFFSET

HELP = "play a trained model and print its returns; --gif/--video record a rollout"
DESCRIPTION = """\
Load a model trained by `sb3-adc train`, run episodes with it in the run's environment (same
wrappers and normalization statistics), and print the return of each episode and their mean.

examples:
  sb3-adc enjoy --algo adc --env Pendulum-v1                      # the latest run in ./logs
  sb3-adc enjoy --algo adc --env Pendulum-v1 --exp-id 2 --model best -n 10
  sb3-adc enjoy --run-dir logs/adc/Pendulum-v1_1 --gif pendulum.gif
"""


PARSER = argparse.ArgumentParser(add_help=False)
PARSER.add_argument("--algo", choices=ALGORITHMS.names(), help="algorithm")
PARSER.add_argument("--env", help="environment id")
PARSER.add_argument("-f", "--log-folder", default="logs", help="log folder (default: logs)")
PARSER.add_argument("--exp-id", type=int, default=0, help="run id (default: 0, the latest run)")
PARSER.add_argument("--run-dir", help="the run's folder (instead of --algo, --env, --log-folder, --exp-id)")
PARSER.add_argument("--model", choices=MODEL_CHOICES, default="final", help="which model of the run (default: final)")
# The RL Zoo's enjoy spellings, for `python -m sb3_adc.zoo enjoy`.
PARSER.add_argument("--load-best", dest="model", action="store_const", const="best", help="the same as --model best")
PARSER.add_argument(
    "--load-last-checkpoint",
    dest="model",
    action="store_const",
    const="last-checkpoint",
    help="the same as --model last-checkpoint",
)
PARSER.add_argument("--no-render", action="store_true", help="accepted for the RL Zoo: nothing is shown on screen anyway")
PARSER.add_argument("--deterministic", action="store_true", help="accepted for the RL Zoo: actions are deterministic")
PARSER.add_argument("-n", "--n-episodes", type=int, default=5, help="episodes to play (default: 5)")
PARSER.add_argument("--seed", type=int, help="environment seed (default: that of the run's evaluations)")
PARSER.add_argument("--stochastic", action="store_true", help="sample actions instead of deterministic ones")
PARSER.add_argument("--gif", metavar="PATH", help="record the first episode as a GIF")
PARSER.add_argument("--video", metavar="PATH", help="record the first episode as a video (.mp4; needs imageio-ffmpeg)")
PARSER.add_argument("--fps", type=int, default=30, help="frames per second of the recording (default: 30)")
PARSER.add_argument(
    "--trust-model-file",
    action="store_true",
    help="unpickle the model file as SB3 does, which runs any code it holds (default: a safe load that builds "
    "only known classes and refuses the rest)",
)
add_runtime_arguments(PARSER)


def _run_dir(args: argparse.Namespace) -> str:
    if args.run_dir is not None:
        return str(args.run_dir)
    if args.algo is None or args.env is None:
        raise CommandError("give --run-dir, or --algo and --env")
    if args.exp_id > 0:
        return os.path.join(args.log_folder, args.algo, f"{env_name(args.env)}_{args.exp_id}")
    run_dir = latest_run_dir(args.log_folder, args.algo, args.env)
    if run_dir is None:
        raise CommandError(f"no run of {args.algo} on {args.env} in {os.path.join(args.log_folder, args.algo)}")
    return run_dir


def run(args: argparse.Namespace) -> int:
    """
    Run the sub-command.

    :param args: The parsed command line
    :return: The exit status
    """
    apply_runtime_arguments(args)
    check_positive(args.n_episodes, "-n/--n-episodes")
    check_positive(args.fps, "--fps")
    settings, config, layout = load_run(_run_dir(args))
    path, statistics = model_path(layout, args.model)
    with refusing_unsafe_files():
        model = load_model(config, path, device=args.device, safe=not args.trust_model_file)
    seed = settings.seed + EVAL_SEED_OFFSET if args.seed is None else args.seed  # default: the run's evaluations'
    print(f"Playing {path} ({settings.algo} on {settings.env_id}) for {args.n_episodes} episodes, seed {seed}")
    record = args.gif is not None or args.video is not None
    rollouts = play(model, config, args.n_episodes, seed, statistics, deterministic=not args.stochastic, record=record)
    for index, (episode_return, length) in enumerate(zip(rollouts.returns, rollouts.lengths, strict=True), start=1):
        print(f"Episode {index}: return {episode_return:.2f}, length {length}")
    print(
        f"Mean return {np.mean(rollouts.returns):.2f} +/- {np.std(rollouts.returns):.2f} over {len(rollouts.returns)} "
        f"{'stochastic' if args.stochastic else 'deterministic'} episodes"
    )
    for output in (args.gif, args.video):
        if output is not None:
            write_recording(rollouts.frames, output, args.fps)
            print(f"Recorded the first episode ({len(rollouts.frames)} frames) in {output}")
    return 0

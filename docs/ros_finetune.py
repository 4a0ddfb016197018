"""Fine-tune the shipped ``ros`` policy on SmartCarArrive-v0 with other env settings.

::

    python docs/ros_finetune.py --timesteps 147456 --goal-tolerance 0.07 --out runs/ft

Loads ``smartcar_gym/pretrained/ros`` (policy.zip and its VecNormalize statistics, which keep
updating) and continues PPO with its hyperparameters (8 envs, 256 steps each per update) on
``SmartCarArrive-v0`` with the given ``goal_tolerance``, the learning rate falling linearly from
``--lr`` to 0. Every ``--save-every`` steps it writes ``<out>/step_<n>/`` (policy.zip,
vecnormalize.pkl, provenance.json): a folder ``Policy.load(Path(...))`` reads with the env
settings it was trained with, for ``docs/ros_goals.py sim --policy``; and the run files
``python -m smartcar_gym.agents.export <out>/step_<n> --out smartcar_gym/pretrained/ros``
reads (model.zip, config.yaml, summary.json). ``--run-files FOLDER`` (re)writes those from
a checkpoint's provenance.json.
"""

from __future__ import annotations

import argparse
import json
import shutil
import time
from pathlib import Path

ENV_ID = "SmartCarArrive-v0"
SOURCE = Path(__file__).resolve().parents[1] / "smartcar_gym" / "pretrained" / "ros"


def write_run_files(folder: Path) -> None:
    """model.zip, config.yaml and summary.json of a checkpoint folder, from its provenance."""
    import yaml

    from smartcar_gym.agents.runs import _versions

    record = json.loads((folder / "provenance.json").read_text())
    shutil.copyfile(folder / "policy.zip", folder / "model.zip")
    config = {k: record[k] for k in ("algo", "env", "env_kwargs", "command", "seed", "n_envs",
                                     "hyperparams")}
    # the keys a smartcar-train config.yaml has (no evaluation or checkpoints during the run)
    config.update(n_timesteps=record["timesteps"], eval_freq=0, eval_episodes=0,
                  checkpoint_freq=0, versions=_versions())
    (folder / "config.yaml").write_text(yaml.safe_dump(config, sort_keys=False))
    (folder / "summary.json").write_text(json.dumps(
        {"num_timesteps": record["timesteps"], "wall_time_s": record["wall_time_s"],
         "fine_tuned_from": record["fine_tuned_from"],
         "fine_tune_timesteps": record["fine_tune_timesteps"]}, indent=2) + "\n")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--timesteps", type=int, default=147456)
    parser.add_argument("--goal-tolerance", type=float, default=0.07)
    parser.add_argument("--lr", type=float, default=3e-4)
    parser.add_argument("--save-every", type=int, default=24576)
    parser.add_argument("--n-envs", type=int, default=8)
    parser.add_argument("--seed", type=int, default=1)
    parser.add_argument("--out", type=Path, default=Path("runs/ros_finetune"))
    parser.add_argument("--run-files", type=Path, metavar="FOLDER",
                        help="only write the run files of a checkpoint folder")
    args = parser.parse_args()
    if args.run_files is not None:
        write_run_files(args.run_files)
        return

    from stable_baselines3 import PPO
    from stable_baselines3.common.callbacks import BaseCallback
    from stable_baselines3.common.vec_env import VecNormalize

    from smartcar_gym.agents.vec_envs import make_vec_env

    env_kwargs = {"goal_tolerance": args.goal_tolerance}
    source = json.loads((SOURCE / "provenance.json").read_text())
    venv = make_vec_env(ENV_ID, args.n_envs, seed=args.seed, env_kwargs=env_kwargs,
                        monitor_dir=args.out / "monitor",
                        monitor_kwargs={"info_keywords": ("is_success",)})
    venv = VecNormalize.load(str(SOURCE / "vecnormalize.pkl"), venv)
    venv.training = True
    model = PPO.load(str(SOURCE / "policy.zip"), env=venv, device="cpu")
    model.set_random_seed(args.seed)
    start_lr = args.lr
    model.learning_rate = lambda progress: start_lr * progress
    model._setup_lr_schedule()
    command = ("python docs/ros_finetune.py " + " ".join(
        f"--{k.replace('_', '-')} {v}" for k, v in vars(args).items() if v is not None))
    started = time.monotonic()

    def save(steps: int) -> None:
        folder = args.out / f"step_{steps}"
        folder.mkdir(parents=True, exist_ok=True)
        model.save(str(folder / "policy.zip"))
        venv.save(str(folder / "vecnormalize.pkl"))
        record = {"algo": "ppo", "env": ENV_ID, "env_kwargs": env_kwargs,
                  "command": command, "fine_tuned_from": {
                      "policy": "smartcar_gym/pretrained/ros",
                      "timesteps": source.get("timesteps"), "command": source.get("command")},
                  "seed": args.seed, "n_envs": args.n_envs,
                  "hyperparams": {**source.get("hyperparams", {}),
                                  "learning_rate": f"lin_{args.lr:g}"},
                  "fine_tune_timesteps": steps,
                  "timesteps": (source.get("timesteps") or 0) + steps,
                  "wall_time_s": time.monotonic() - started}
        (folder / "provenance.json").write_text(json.dumps(record, indent=2) + "\n")
        write_run_files(folder)
        print(f"saved {folder} after {time.monotonic() - started:.0f} s", flush=True)

    class Saver(BaseCallback):
        def _on_step(self) -> bool:
            if self.num_timesteps % args.save_every == 0:
                save(self.num_timesteps)
            return True

    model.learn(args.timesteps, callback=Saver(), reset_num_timesteps=True)
    if args.timesteps % args.save_every:
        save(model.num_timesteps)
    venv.close()


if __name__ == "__main__":
    main()

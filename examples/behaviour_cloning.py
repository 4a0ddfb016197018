"""Behaviour cloning from a Minari dataset of the shipped policy's episodes.

Reads every transition of ``DATASET`` (written by ``smartcar-eval --minari``), fits a small
MLP (torch: 21 -> 64 -> 64 -> 2, tanh, inputs standardised with the data's mean and std) to
the recorded actions with a mean squared error, then evaluates the clone on episodes of the
env that ``dataset.recover_environment()`` gives (its kwargs: the dataset's engine), seeded
after the dataset's own seeds, in one batch. Prints the fit's loss and the success rate.

    smartcar-eval --pretrained --episodes 1000 --vectorization batched \\
        --minari smartcar/default-pybullet-v0
    python examples/behaviour_cloning.py smartcar/default-pybullet-v0

Needs the ``train`` and ``minari`` extras (docs/export.md).
"""

from __future__ import annotations

import argparse
import time

import minari
import numpy as np
import torch
from torch import nn

from smartcar_gym.agents.episodes import evaluate_batched_episodes
from smartcar_gym.agents.records import summarize
from smartcar_gym.policy import Policy


class Clone:
    """The fitted MLP as an SB3-like model (``predict`` on a batch of raw observations)."""

    observation_space = None

    def __init__(self, net: nn.Module, mean: np.ndarray, std: np.ndarray) -> None:
        self.net, self.mean, self.std = net, mean, std

    def predict(self, obs: np.ndarray, deterministic: bool = True) -> tuple[np.ndarray, None]:
        x = torch.as_tensor((np.asarray(obs, np.float32) - self.mean) / self.std)
        with torch.no_grad():
            return self.net(x).numpy(), None


def transitions(dataset: minari.MinariDataset) -> tuple[np.ndarray, np.ndarray]:
    """Every (observation, action) pair of the dataset; actions clipped as the env clips."""
    obs, actions = [], []
    for episode in dataset.iterate_episodes():
        obs.append(episode.observations[:-1])
        actions.append(np.clip(episode.actions, -1.0, 1.0))
    return np.concatenate(obs).astype(np.float32), np.concatenate(actions).astype(np.float32)


def fit(obs: np.ndarray, actions: np.ndarray, epochs: int, seed: int) -> Clone:
    """An MLP fitted to ``actions`` with Adam, minibatches of 256."""
    torch.manual_seed(seed)
    mean, std = obs.mean(0), obs.std(0) + 1e-6
    x, y = torch.as_tensor((obs - mean) / std), torch.as_tensor(actions)
    net = nn.Sequential(nn.Linear(obs.shape[1], 64), nn.Tanh(), nn.Linear(64, 64), nn.Tanh(),
                        nn.Linear(64, actions.shape[1]))
    optimiser = torch.optim.Adam(net.parameters(), lr=1e-3)
    generator = torch.Generator().manual_seed(seed)
    for epoch in range(epochs):
        order = torch.randperm(len(x), generator=generator)
        total = 0.0
        for start in range(0, len(x), 256):
            batch = order[start:start + 256]
            loss = nn.functional.mse_loss(net(x[batch]), y[batch])
            optimiser.zero_grad()
            loss.backward()
            optimiser.step()
            total += loss.item() * len(batch)
        if epoch % 10 == 9 or epoch == epochs - 1:
            print(f"epoch {epoch + 1}: mean squared error {total / len(x):.5f}")
    return Clone(net.eval(), mean, std)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("dataset_id")
    parser.add_argument("--epochs", type=int, default=40)
    parser.add_argument("--episodes", type=int, default=100, help="evaluation episodes")
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args()
    torch.set_num_threads(1)
    dataset = minari.load_dataset(args.dataset_id)
    obs, actions = transitions(dataset)
    print(f"{dataset.total_episodes} episodes, {len(obs)} transitions")
    started = time.perf_counter()
    clone = fit(obs, actions, args.epochs, args.seed)
    print(f"fitted in {time.perf_counter() - started:.0f} s")
    env = dataset.recover_environment()
    env_id, env_kwargs = env.spec.id, dict(env.spec.kwargs)
    env.close()
    first = dataset.total_episodes  # seeds the dataset did not use (it used 0..N-1)
    records = evaluate_batched_episodes(Policy(clone, env_id=env_id, env_kwargs=env_kwargs),
                                        env_id, n_episodes=args.episodes, n_envs=args.episodes,
                                        seed=first, env_kwargs=env_kwargs)
    summary = summarize(records)
    engine = env_kwargs.get("engine", "pybullet")
    print(f"behaviour clone on {env_id} ({engine}), seeds {first}..{first + args.episodes - 1}:"
          f" success {summary['success_rate']:.0%}, mean return {summary['mean_return']:.2f}")


if __name__ == "__main__":
    main()

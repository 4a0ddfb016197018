"""Old path of ``smartcar_gym.agents.zoo_runs`` (rl-baselines3-zoo run folders):
its names still import from here."""

from smartcar_gym.agents import moved

__getattr__ = moved("smartcar_gym.agents.zoo_runs")

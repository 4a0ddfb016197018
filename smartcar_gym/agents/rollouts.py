"""Old path of ``smartcar_gym.agents.episodes`` (the episodes, their records and summary):
its names still import from here."""

from smartcar_gym.agents import moved

__getattr__ = moved("smartcar_gym.agents.episodes")

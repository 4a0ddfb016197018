"""Old path of ``smartcar_gym.agents.models`` (a saved model's files and normaliser):
its names still import from here."""

from smartcar_gym.agents import moved

__getattr__ = moved("smartcar_gym.agents.models")

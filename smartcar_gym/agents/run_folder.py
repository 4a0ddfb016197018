"""Old path of ``smartcar_gym.agents.runs`` (a run's folder, new or resumed):
its names still import from here."""

from smartcar_gym.agents import moved

__getattr__ = moved("smartcar_gym.agents.runs")

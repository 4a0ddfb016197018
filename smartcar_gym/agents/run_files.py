"""Old path of ``smartcar_gym.agents.atomic_files`` and ``runs`` (atomic writes, checkpoint
names): its names still import from here."""

from smartcar_gym.agents import moved

__getattr__ = moved("smartcar_gym.agents.atomic_files", "smartcar_gym.agents.runs")

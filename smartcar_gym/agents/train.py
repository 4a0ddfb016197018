"""Old path of ``smartcar_gym.agents.cli_train`` (the ``smartcar-train`` command): its names still
import from here, and ``python -m smartcar_gym.agents.train`` runs the command."""

import sys

from smartcar_gym.agents import moved
from smartcar_gym.agents.cli_train import main

__getattr__ = moved("smartcar_gym.agents.cli_train")

if __name__ == "__main__":
    sys.exit(main())

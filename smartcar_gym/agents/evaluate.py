"""Old path of ``smartcar_gym.agents.cli_eval`` (the ``smartcar-eval`` command): its names still
import from here, and ``python -m smartcar_gym.agents.evaluate`` runs the command."""

import sys

from smartcar_gym.agents import moved
from smartcar_gym.agents.cli_eval import main

__getattr__ = moved("smartcar_gym.agents.cli_eval")

if __name__ == "__main__":
    sys.exit(main())

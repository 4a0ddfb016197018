"""``python -m smartcar_gym.ros``: the ``smartcar-ros`` command."""

import sys

from smartcar_gym.ros.cli import main

sys.exit(main())

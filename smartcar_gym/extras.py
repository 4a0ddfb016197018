"""Which of the package's optional extras are installed, found without importing them."""

from __future__ import annotations

import importlib.util

TRAIN_EXTRA = 'pip install "smartcar-gym[train]"'


def missing_modules(modules: tuple[str, ...]) -> list[str]:
    """The names in ``modules`` that cannot be imported (found without importing them)."""
    missing = []
    for name in modules:
        try:
            found = importlib.util.find_spec(name) is not None
        except (ImportError, ValueError):
            found = False
        if not found:
            missing.append(name)
    return missing

"""process_start: the commands' processes collect young garbage in larger batches, set
before ``main`` runs, and end through ``exit_now`` with its code; code that calls ``main``
keeps its own settings."""

from __future__ import annotations

import gc
import importlib

import pytest

from smartcar_gym.agents import process_start
from smartcar_gym.agents.process_start import YOUNG_THRESHOLD, start_process


@pytest.fixture
def thresholds():
    kept = gc.get_threshold()
    yield kept
    gc.set_threshold(*kept)


def test_start_process_raises_only_the_first_threshold(thresholds):
    gc.set_threshold(700, 7, 9)
    start_process()
    assert gc.get_threshold() == (YOUNG_THRESHOLD, 7, 9)
    assert YOUNG_THRESHOLD > 700  # Python's default


@pytest.mark.parametrize("command", ["cli_train", "cli_eval"])
def test_the_command_sets_up_its_process_before_main(command, thresholds, monkeypatch):
    module = importlib.import_module(f"smartcar_gym.agents.{command}")
    gc.set_threshold(700, 10, 10)
    seen = []

    def main():
        seen.append(gc.get_threshold())
        return 3

    def exit_now(code):
        raise SystemExit(code)

    monkeypatch.setattr(module, "main", main)
    monkeypatch.setattr(process_start, "exit_now", exit_now)
    with pytest.raises(SystemExit) as stop:
        module.run()
    assert stop.value.code == 3
    assert seen == [(YOUNG_THRESHOLD, 10, 10)]


def test_main_alone_leaves_the_thresholds_as_they_are(thresholds, tmp_path):
    from smartcar_gym.agents import cli_eval

    gc.set_threshold(700, 10, 10)
    with pytest.raises(SystemExit):
        cli_eval.main(["--help"])
    assert gc.get_threshold() == (700, 10, 10)

"""Watching and stopping a training run: a progress bar over its steps
(``ProgressBarCallback``) and a clean stop on Ctrl-C or SIGTERM (``StopOnSigint``)."""

from __future__ import annotations

import signal
import sys
import threading
import time
from typing import TYPE_CHECKING, Any

import numpy as np
from stable_baselines3.common.callbacks import BaseCallback

if TYPE_CHECKING:
    from smartcar_gym.agents.callbacks import SuccessEvalCallback

__all__ = ["ProgressBarCallback", "StopOnSigint"]


class ProgressBarCallback(BaseCallback):
    """A tqdm bar over environment steps showing steps/s and the latest success rates."""

    def __init__(self, total_timesteps: int, eval_callback: SuccessEvalCallback | None = None,
                 refresh_s: float = 0.5) -> None:
        super().__init__()
        self.total_timesteps = int(total_timesteps)
        self.eval_callback = eval_callback
        self.refresh_s = refresh_s
        self.bar = None
        self._shown = 0
        self._last_refresh = 0.0

    def _on_training_start(self) -> None:
        from tqdm.auto import tqdm

        self._shown = self.num_timesteps
        self.bar = tqdm(
            total=self.total_timesteps, initial=self.num_timesteps, unit="step",
            unit_scale=True, dynamic_ncols=True, smoothing=0.05, desc="training",
        )

    def _on_step(self) -> bool:
        if self.bar is None:
            return True
        self.bar.update(self.num_timesteps - self._shown)
        self._shown = self.num_timesteps
        now = time.monotonic()
        if now - self._last_refresh >= self.refresh_s:
            self._last_refresh = now
            postfix = {}
            buffer = getattr(self.model, "ep_success_buffer", None)
            if buffer:
                postfix["train_success"] = f"{np.mean(buffer):.0%}"
            last = None if self.eval_callback is None else self.eval_callback.last_result
            if last is not None:
                postfix["eval_success"] = f"{last.success_rate:.0%}"
            self.bar.set_postfix(postfix, refresh=False)
        return True

    def _on_training_end(self) -> None:
        self.close()

    def close(self) -> None:
        """Close the bar (also after an interrupted run)."""
        if self.bar is not None:
            self.bar.close()
            self.bar = None


class StopOnSigint(BaseCallback):
    """While active (``with``), the first Ctrl-C (SIGINT) or SIGTERM makes training stop
    cleanly at the next step; ``signum`` records which.

    A KeyboardInterrupt in the middle of a ``SubprocVecEnv`` exchange would leave its pipes out
    of step, so the signal only sets ``requested`` and ``_on_step`` returns False; SB3 then
    ends ``learn()``. A second signal raises KeyboardInterrupt (stop at once).
    """

    SIGNALS = (signal.SIGINT, signal.SIGTERM)

    def __init__(self) -> None:
        super().__init__()
        self.requested = False
        self.signum: int | None = None
        self._previous: dict[int, Any] = {}

    def __enter__(self) -> StopOnSigint:
        if threading.current_thread() is threading.main_thread():
            self._previous = {s: signal.signal(s, self._handle) for s in self.SIGNALS}
        return self

    def __exit__(self, *exc: object) -> None:
        for signum, previous in self._previous.items():
            signal.signal(signum, previous)
        self._previous = {}

    def _handle(self, signum: int, frame: Any) -> None:
        if self.requested:
            raise KeyboardInterrupt
        self.requested, self.signum = True, signum
        name = "Ctrl-C" if signum == signal.SIGINT else signal.Signals(signum).name
        print(f"\n{name}: stopping after this step and saving a checkpoint "
              f"({name} again to stop at once)", file=sys.stderr)

    def _on_step(self) -> bool:
        return not self.requested

"""A Gymnasium ``VectorEnv`` seen as a Stable-Baselines3 ``VecEnv`` (``--vectorization batched``).

SB3 resets a finished env at once and hands its last observation over in
``info["terminal_observation"]``: Gymnasium's ``SameStep`` autoreset, with ``final_obs`` and
``final_info``. ``GymVectorVecEnv`` turns the vector env's batched ``info`` into SB3's list of
per-env dicts: ``is_success`` (from the last step of an episode that ended),
``TimeLimit.truncated``, ``terminal_observation``. Wrap it in SB3's ``VecMonitor`` for
episode returns, lengths and success in the Monitor file, as ``vec_envs.make_batched_vec_env``
does.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import gymnasium as gym
import numpy as np
from gymnasium.vector import AutoresetMode
from stable_baselines3.common.vec_env import VecEnv


class GymVectorVecEnv(VecEnv):
    """SB3's ``VecEnv`` over a Gymnasium ``VectorEnv`` made with ``autoreset_mode="SameStep"``.

    ``seed(s)`` makes the next ``reset`` seed env i with ``s + i``, as SB3's own VecEnvs do.
    ``get_attr``/``set_attr``/``env_method`` act on the vector env itself (one object for all
    cars), answering once per requested index.
    """

    def __init__(self, venv: gym.vector.VectorEnv) -> None:
        mode = venv.metadata.get("autoreset_mode")
        if mode != AutoresetMode.SAME_STEP:
            raise ValueError(f"GymVectorVecEnv needs a vector env with autoreset_mode='SameStep' "
                             f"(SB3 resets at once), got {mode!r}")
        self.venv = venv
        super().__init__(venv.num_envs, venv.single_observation_space,
                         venv.single_action_space)
        self.render_mode = getattr(venv, "render_mode", None)
        self._actions: np.ndarray | None = None

    def reset(self) -> np.ndarray:
        seeds = list(self._seeds) if any(s is not None for s in self._seeds) else None
        options = self._options[0] if self._options and self._options[0] else None
        obs, info = self.venv.reset(seed=seeds, options=options)
        self._reset_seeds()
        self._reset_options()
        self.reset_infos = self._infos(info, self.num_envs)
        return obs

    def step_async(self, actions: np.ndarray) -> None:
        self._actions = actions

    def step_wait(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, list[dict[str, Any]]]:
        obs, rewards, terminated, truncated, info = self.venv.step(self._actions)
        dones = terminated | truncated
        infos = self._infos(info, self.num_envs)
        final_obs, final_info = info.get("final_obs"), info.get("final_info", {})
        done = np.flatnonzero(dones)
        lasts = self._infos(final_info, self.num_envs) if len(done) else []
        for i in done.tolist():
            last = lasts[i]
            last["terminal_observation"] = final_obs[i]
            last["TimeLimit.truncated"] = bool(truncated[i] and not terminated[i])
            infos[i] = last
        return obs, rewards.astype(np.float32), dones, infos

    @staticmethod
    def _infos(info: dict[str, Any], n: int) -> list[dict[str, Any]]:
        """Each env's entries of a Gymnasium vector ``info`` (those its ``_key`` mask marks),
        numbers as Python's: one pass over the keys, not one per env (16 cars' infos took 7 %
        of the main job's rollouts a key and an env at a time)."""
        out: list[dict[str, Any]] = [{} for _ in range(n)]
        for key, value in info.items():
            if key.startswith("_") or key in ("final_obs", "final_info") or isinstance(
                    value, dict):
                continue
            if isinstance(value, np.ndarray):  # numbers as Python's (.item()), rows as arrays
                items = value.tolist() if value.ndim == 1 and value.dtype != object else list(
                    value)
            else:
                items = [v.item() if isinstance(v, np.generic) else v for v in value]
            mask = info.get(f"_{key}")
            marked = [True] * n if mask is None else np.asarray(mask).tolist()
            for i, (one, item) in enumerate(zip(out, items, strict=True)):
                if marked[i]:
                    one[key] = item
        return out

    def close(self) -> None:
        self.venv.close()

    def render(self, mode: str | None = None) -> np.ndarray | None:
        return self.venv.render()

    def get_images(self) -> Sequence[np.ndarray | None]:
        return [self.venv.render()]

    def get_attr(self, attr_name: str, indices: Any = None) -> list[Any]:
        return [getattr(self.venv, attr_name)] * len(self._get_indices(indices))

    def set_attr(self, attr_name: str, value: Any, indices: Any = None) -> None:
        setattr(self.venv, attr_name, value)

    def env_method(self, method_name: str, *method_args: Any, indices: Any = None,
                   **method_kwargs: Any) -> list[Any]:
        result = getattr(self.venv, method_name)(*method_args, **method_kwargs)
        return [result] * len(self._get_indices(indices))

    def env_is_wrapped(self, wrapper_class: type, indices: Any = None) -> list[bool]:
        return [False] * len(self._get_indices(indices))

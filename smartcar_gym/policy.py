"""A trained policy as one object: its SB3 model, its observation normaliser and its env.

``Policy.load(source)`` takes a shipped policy's name (``"default"``, ``"robust"``, ``"nav"``:
``PRETRAINED_POLICIES``), a model ``.zip`` or a run folder of ``smartcar-train`` or
rl-baselines3-zoo (its final model), and finds what ``smartcar-eval`` and ``smartcar-ros
policy`` find: the algorithm, the env id and env kwargs the model was trained with, and its
VecNormalize statistics. ``act(obs)`` turns one observation (an array, or a dict of arrays for
``SmartCarGoal-v0``) into an action: normalised with the frozen statistics, then the model's
``predict`` on a batch of one, so actions do not depend on batching::

    from smartcar_gym.policy import Policy

    policy = Policy.load("default")        # or "runs/ppo_SmartCar-v0_s0", "model.zip"
    env = policy.make_env()                # gym.make(policy.env_id, **policy.env_kwargs)
    obs, _ = env.reset(seed=0)
    done = False
    while not done:
        obs, reward, terminated, truncated, info = env.step(policy.act(obs))
        done = terminated or truncated
    env.close()

Trust: model zips and VecNormalize files are pickles (loading one runs the code it holds). A
normaliser is unpickled only when named (``normalizer=``) or assigned to the model by its
place (``agents.models``: a smartcar-train run, an exported or shipped policy, a zoo run
that says ``normalize``); otherwise none is loaded and ``warning`` says why that matters. The
env id, env kwargs and engine a run's or an exported policy's files name are data, checked by
``registration.check_policy_env`` before anything is loaded (docs/export.md, "What a policy
file can and cannot make the package do"); ``make_env`` refuses an id that names a module.

Bad input raises ``PolicyError`` (a ``ValueError``) with one line naming the file and what was
expected. The lines name the options of the commands built on this module: ``--model``,
``--algo`` and ``--vecnormalize`` are ``source``, ``algo`` and ``normalizer`` here. Loading
needs the ``train`` extra (Stable-Baselines3, torch): ``ImportError`` naming it otherwise.
"""

from smartcar_gym.agents.models import PRETRAINED_POLICIES
from smartcar_gym.agents.policies import (
    DEFAULT_ENV_ID,
    ObsNormalizer,
    Policy,
    PolicyError,
    as_policy,
    choose_normalizer,
)

__all__ = ["DEFAULT_ENV_ID", "PRETRAINED_POLICIES", "ObsNormalizer", "Policy", "PolicyError",
           "as_policy", "choose_normalizer"]

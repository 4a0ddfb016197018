"""optimizers.foreach_updates: the models' Adam optimizers on torch's multi-tensor update,
which gives the same parameters bit for bit as the update one tensor at a time."""

from __future__ import annotations

import pytest

torch = pytest.importorskip("torch")
pytest.importorskip("stable_baselines3")

from smartcar_gym.agents.optimizers import foreach_updates, model_optimizers  # noqa: E402


def _adam_run(foreach: bool, steps: int = 60) -> list[torch.Tensor]:
    """A small tanh MLP (as SB3's policies) trained with Adam on fixed random data."""
    torch.manual_seed(0)
    net = torch.nn.Sequential(torch.nn.Linear(12, 64), torch.nn.Tanh(), torch.nn.Linear(64, 64),
                              torch.nn.Tanh(), torch.nn.Linear(64, 3))
    optimizer = torch.optim.Adam(net.parameters(), lr=1.5e-3, eps=1e-5, foreach=foreach)
    data = torch.randn(256, 12, generator=torch.Generator().manual_seed(1))
    target = torch.randn(256, 3, generator=torch.Generator().manual_seed(2))
    for _ in range(steps):
        optimizer.zero_grad()
        loss = ((net(data) - target) ** 2).mean()
        loss.backward()
        torch.nn.utils.clip_grad_norm_(net.parameters(), 0.5)
        optimizer.step()
    return [p.detach().clone() for p in net.parameters()]


def test_the_multi_tensor_update_gives_the_same_parameters_bit_for_bit():
    one_at_a_time, foreach = _adam_run(False), _adam_run(True)
    start = _adam_run(False, steps=0)
    for a, b, s in zip(one_at_a_time, foreach, start, strict=True):
        assert not torch.equal(a, s)  # they trained
        assert torch.equal(a, b)


def _model(algo: str, **kwargs):
    import gymnasium as gym
    from stable_baselines3 import PPO, SAC, TD3

    env = gym.make("Pendulum-v1")
    cls = {"ppo": PPO, "sac": SAC, "td3": TD3}[algo]
    return cls("MlpPolicy", env, device="cpu", **kwargs)


@pytest.mark.parametrize(("algo", "count"), [("ppo", 1), ("sac", 3), ("td3", 2)])
def test_every_adam_optimizer_of_a_model_takes_the_multi_tensor_update(algo, count):
    model = _model(algo)
    optimizers = model_optimizers(model)
    assert len(optimizers) == count  # PPO's policy; the actor's, critics' (and SAC's alpha's)
    assert all(g["foreach"] is None for o in optimizers for g in o.param_groups)
    assert foreach_updates(model) == count
    assert all(g["foreach"] is True for o in optimizers for g in o.param_groups)
    assert foreach_updates(model) == 0  # set already


@pytest.mark.parametrize("chosen", [{"foreach": False}, {"fused": True}])
def test_an_update_the_hyperparameters_chose_is_kept(chosen):
    model = _model("ppo", policy_kwargs={"optimizer_kwargs": {"eps": 1e-5, **chosen}})
    assert foreach_updates(model) == 0
    group = model.policy.optimizer.param_groups[0]
    assert group["foreach"] is chosen.get("foreach")
    assert bool(group["fused"]) is chosen.get("fused", False)


def test_another_optimizer_is_left_alone():
    model = _model("ppo", policy_kwargs={"optimizer_class": torch.optim.RMSprop})
    assert foreach_updates(model) == 0
    assert model.policy.optimizer.param_groups[0]["foreach"] is None

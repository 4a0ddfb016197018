"""The models' optimizers on the CPU: Adam's multi-tensor update, the same numbers sooner.

torch's Adam (and AdamW) update their parameters one tensor after another unless told
``foreach=True``, their default on the CPU; with it, each of the update's operations runs once
over every tensor (``torch._foreach_*``). The arithmetic is the same operation for operation,
so the parameters come out the same bit for bit (``tests/test_optimizers.py`` checks it on
the installed torch; the README's training gives the same ``policy.pth`` either way), in less
time: an update of the main job (40 minibatches of 256, two 64 x 64 MLPs) took 0.957 of the
time (the median of 40 rounds interleaved, 2026-12-01, the 2-core machine).

``foreach_updates`` turns it on for a Stable-Baselines3 model's Adam optimizers where the
hyperparameters left it unset (``optimizer_kwargs``' ``foreach`` or ``fused``, when given, are
kept). Adam's fused kernel is not this: it changes the numbers (docs/performance.md).
"""

from __future__ import annotations

from typing import Any


def model_optimizers(model: Any) -> list[Any]:
    """The torch optimizers a Stable-Baselines3 model holds: its policy's and its
    sub-networks' (PPO's ``policy.optimizer``; SAC's and TD3's actor's and critic's) and its
    own (SAC's entropy coefficient's), each once."""
    import torch

    found: dict[int, Any] = {}
    for holder in (model, *model.policy.modules()):
        for value in vars(holder).values():
            if isinstance(value, torch.optim.Optimizer):
                found.setdefault(id(value), value)
    return list(found.values())


def foreach_updates(model: Any) -> int:
    """Adam's multi-tensor update (``foreach=True``) in each of the model's Adam or AdamW
    parameter groups that has neither ``foreach`` nor ``fused`` set; returns how many groups
    it set."""
    import torch

    changed = 0
    for optimizer in model_optimizers(model):
        if not isinstance(optimizer, (torch.optim.Adam, torch.optim.AdamW)):
            continue
        for group in optimizer.param_groups:
            if group.get("foreach") is None and not group.get("fused"):
                group["foreach"] = True
                changed += 1
    return changed

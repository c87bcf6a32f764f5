"""
Optimizer steps and Polyak updates for the fast update path of SB3's TD3 family (ADC, and TD3 with an averaged actor).

With the small networks these algorithms train on the CPU, a gradient step is a few hundred small tensor operations
and their dispatch costs more than their arithmetic. SB3 leaves Adam's ``foreach``/``fused`` unset, and on the CPU
torch then takes its per-parameter Python loop (about ten operations per parameter tensor); SB3's ``polyak_update``
zips the parameter lists, two operations per tensor. Here Adam defaults to its fused kernel (one call for all
tensors, supported on the CPU and CUDA), and a Polyak update is one ``torch._foreach_lerp_`` call. Both change float
rounding only.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import torch as th
from torch.optim import optimizer as torch_optimizer

#: The optimizers whose ``fused`` kernel the fast path chooses when neither ``fused`` nor ``foreach`` is set.
FUSED_OPTIMIZERS: tuple[type[th.optim.Optimizer], ...] = (th.optim.Adam, th.optim.AdamW)


def fast_optimizer_kwargs(
    optimizer_class: type[th.optim.Optimizer], optimizer_kwargs: dict[str, Any] | None
) -> dict[str, Any]:
    """
    The optimizer's keyword arguments with ``fused=True`` added for Adam and AdamW when the caller set neither
    ``fused`` nor ``foreach``: the caller's explicit choice wins.

    :param optimizer_class: The optimizer class of the policy
    :param optimizer_kwargs: The caller's keyword arguments (``None``: none)
    :return: A new dict
    """
    kwargs = dict(optimizer_kwargs or {})
    if issubclass(optimizer_class, FUSED_OPTIMIZERS) and kwargs.get("fused") is None and kwargs.get("foreach") is None:
        kwargs["fused"] = True
    return kwargs


def select_optimizer_implementation(optimizers: Sequence[th.optim.Optimizer], fast: bool) -> None:
    """
    Choose the implementation of the optimizers' steps, in their parameter groups (which a loaded optimizer state
    overwrites, so this is called at each ``train``): for the plain path (``fast=False``), SB3's, ``fused`` and
    ``foreach`` unset (the per-parameter loop on the CPU); for the fast path, the fused kernel of Adam and AdamW
    where neither ``fused`` nor ``foreach`` is set (a model file saved before the fast path existed, or an optimizer
    built without :func:`fast_optimizer_kwargs`).

    :param optimizers: The optimizers
    :param fast: Whether to train with the fast update path
    """
    for optimizer in optimizers:
        fusable = isinstance(optimizer, FUSED_OPTIMIZERS)
        for group in optimizer.param_groups:
            if not fast:
                if group.get("fused"):
                    group["fused"] = False
                if group.get("foreach"):
                    group["foreach"] = None
            elif fusable and group.get("fused") is None and group.get("foreach") is None:
                group["fused"] = True


def foreach_polyak_update(parameters: Sequence[th.Tensor], target_parameters: Sequence[th.Tensor], tau: float) -> None:
    """
    SB3's ``polyak_update``, ``target <- (1 - tau) target + tau parameter``, as one ``torch._foreach_lerp_`` call over
    all the tensors (the same update up to float rounding).

    :param parameters: The parameters to move towards
    :param target_parameters: The parameters to update, in place
    :param tau: The soft update coefficient, in ``[0, 1]``
    """
    if len(parameters) != len(target_parameters):
        raise ValueError(f"{len(parameters)} parameters for {len(target_parameters)} target parameters.")
    if target_parameters:
        with th.no_grad():
            th._foreach_lerp_(list(target_parameters), list(parameters), tau)


class FusedAdamStep:
    """
    The step of a fused Adam or AdamW (``fused=True``), with its tensor lists gathered once instead of at every step.

    ``Optimizer.step`` costs several times its fused kernel with small networks: per call it walks every parameter
    in Python to gather the gradients and the state, and groups them by device. This calls the same kernel
    (``torch._fused_adam_`` or ``torch._fused_adamw_``, as ``torch.optim.adam._fused_adam`` does, so the update is the
    same to the bit) on lists checked by identity at each step, and falls back to ``optimizer.step()`` whenever
    that would differ: another optimizer class or option, step hooks, a parameter without a gradient, or a state
    replaced (a loaded optimizer state). Gradients are zeroed in place (:meth:`zero_grad`), so that they stay the
    tensors gathered.

    :param optimizer: The optimizer (its parameter groups are read at each step: learning-rate changes apply)
    """

    def __init__(self, optimizer: th.optim.Optimizer):
        self.optimizer = optimizer
        self._state: object = None
        self._groups: list[tuple[dict[str, Any], list[th.Tensor], list[th.Tensor], list[list[th.Tensor]]]] = []

    def _usable(self) -> bool:
        optimizer = self.optimizer
        if type(optimizer) not in FUSED_OPTIMIZERS:
            return False
        if optimizer._optimizer_step_pre_hooks or optimizer._optimizer_step_post_hooks:
            return False
        return not (torch_optimizer._global_optimizer_pre_hooks or torch_optimizer._global_optimizer_post_hooks)

    def _gather(self) -> bool:
        """Gather the tensor lists of every group; whether the fast step applies to all of them."""
        optimizer = self.optimizer
        self._groups = []
        for group in optimizer.param_groups:
            if not group.get("fused") or group.get("amsgrad") or group.get("capturable") or group.get("differentiable"):
                return False
            if isinstance(group["lr"], th.Tensor) or any(isinstance(beta, th.Tensor) for beta in group["betas"]):
                return False
            params: list[th.Tensor] = list(group["params"])
            grads = [param.grad for param in params]
            states = [optimizer.state.get(param) for param in params]
            if any(grad is None for grad in grads) or any(not state for state in states):
                return False
            kinds = {(tensor.device, tensor.dtype) for tensor in params}
            if len(kinds) > 1 or any(grad.is_sparse for grad in grads):  # type: ignore[union-attr]
                return False
            state_lists = [[state[key] for state in states] for key in ("exp_avg", "exp_avg_sq", "step")]  # type: ignore[index]
            self._groups.append((group, params, grads, state_lists))  # type: ignore[arg-type]
        self._state = optimizer.state
        return True

    def _current(self) -> bool:
        """Whether the gathered lists are still the optimizer's (same state, same gradient tensors)."""
        if self._state is not self.optimizer.state or not self._groups:
            return False
        for group, params, grads, _ in self._groups:
            current = group["params"]
            if len(current) != len(params) or any(a is not b for a, b in zip(current, params, strict=True)):
                return False
            if any(param.grad is not grad for param, grad in zip(params, grads, strict=True)):
                return False
        return True

    def zero_grad(self) -> None:
        """Zero the gathered gradients in place (the optimizer's own ``zero_grad`` until they are gathered)."""
        if self._current():
            th._foreach_zero_([grad for _, _, grads, _ in self._groups for grad in grads])
        else:
            self.optimizer.zero_grad(set_to_none=False)

    def step(self) -> None:
        """One optimizer step: the fused kernel on the gathered lists, or ``optimizer.step()``."""
        if not self._usable() or not (self._current() or self._gather()):
            self._groups = []
            self.optimizer.step()
            return
        with th.no_grad():
            for group, params, grads, (exp_avgs, exp_avg_sqs, steps) in self._groups:
                th._foreach_add_(steps, 1)
                decoupled = group.get("decoupled_weight_decay", isinstance(self.optimizer, th.optim.AdamW))
                kernel = th._fused_adamw_ if decoupled else th._fused_adam_
                beta1, beta2 = group["betas"]
                kernel(
                    params,
                    grads,
                    exp_avgs,
                    exp_avg_sqs,
                    [],
                    steps,
                    amsgrad=False,
                    lr=group["lr"],
                    beta1=beta1,
                    beta2=beta2,
                    weight_decay=group["weight_decay"],
                    eps=group["eps"],
                    maximize=group["maximize"],
                    grad_scale=None,
                    found_inf=None,
                )

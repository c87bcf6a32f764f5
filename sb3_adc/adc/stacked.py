"""
The critic networks of a twin (or larger) ``"legendre"`` critic evaluated as one batched module: ADC's fast update.

With the small networks ADC is used with (the lidar entries: 100 and 20 units, batch 64), a gradient step is a few
hundred small tensor operations, each costing more in dispatch than in arithmetic; twin critics evaluated one after
the other double the critic's share. :class:`StackedCritics` evaluates all of them at once: each layer is one
``baddbmm`` over weights stacked along a leading critic dimension (the first layer, which reads the shared state
features, one ``linear`` over the concatenated weights), so the forward and backward passes cost the operations of
one critic.

The stored parameters stay the per-critic modules' (``qf0.trunk.0.weight``, ...): saved files, ``state_dict`` and the
optimizer's state are those of the plain critic, and files saved before load unchanged. The stacked tensors are built
from them and the per-critic parameters are then made views of their rows (``param.data = stacked[i]``), so the
optimizer's in-place steps, Polyak updates and ``load_state_dict`` (which copies in place) move both at once; the
per-critic gradients are views of the stacked gradient in the same way. Anything that gives a parameter new storage
(``.to(other_device)``, ``deepcopy``) breaks the link: :meth:`StackedCritics.link` checks it at each ``train`` call and
rebuilds it from the parameters' current values.

Used by :class:`~sb3_adc.adc.adc.ADC` with ``fast_update=True``: it changes float rounding only (the per-critic path
is tested against it, ``tests/adc/test_fast_update.py``).
"""

from __future__ import annotations

import torch as th
from torch import nn
from torch.nn import functional as F

from sb3_adc.adc.legendre import LegendreAdvantageNetwork
from sb3_adc.adc.policies import DuelingIntervalCritic

#: One layer of a stacked MLP: a linear layer's (weight, bias) indices into the stacked tensors, or an activation.
_Layer = tuple[int, int] | nn.Module


def stackable(critic: DuelingIntervalCritic) -> bool:
    """
    Whether :class:`StackedCritics` can evaluate the critic: several ``"legendre"`` networks with mean aggregation
    (the default critic), made of linear layers and parameter-free activations, and a features extractor without
    parameters (the critic's own parameters are then exactly its networks').

    :param critic: The critic
    """
    if critic.n_critics < 2 or critic.critic_design != "legendre" or critic.aggregation != "mean":
        return False
    if any(True for _ in critic.features_extractor.parameters()):
        return False
    for network in critic.q_networks:
        assert isinstance(network, LegendreAdvantageNetwork)
        for sequence in _sequences(network):
            for module in sequence:
                if isinstance(module, nn.Linear):
                    if module.bias is None:
                        return False
                elif any(True for _ in module.parameters()):
                    return False
    return True


def _sequences(network: LegendreAdvantageNetwork) -> list[nn.Sequential]:
    """The trunk and the heads of a ``"legendre"`` network (``heads`` as a one-layer sequence when fused)."""
    if network.fused_heads:
        return [network.trunk, nn.Sequential(network.heads)]
    return [network.trunk, network.value_head, network.coefficient_head]


class StackedCritics:
    """
    The networks of a critic whose :func:`stackable` is true, with their parameters stacked along a leading critic
    dimension, evaluated in one batched pass (see the module's docstring).

    :param critic: The critic (online or target)
    :param requires_grad: Whether the stacked parameters collect gradients (the online critic; not the target)
    """

    def __init__(self, critic: DuelingIntervalCritic, requires_grad: bool):
        if not stackable(critic):
            raise ValueError("StackedCritics needs a critic for which `stackable(critic)` is true.")
        self.critic = critic
        self.requires_grad = requires_grad
        self.networks = [network for network in critic.q_networks if isinstance(network, LegendreAdvantageNetwork)]
        first = self.networks[0]
        names = [name for name, _ in first.named_parameters()]
        # members[k]: the k-th parameter of every network; stacked[k]: their stack, whose rows they view.
        self.members = [[dict(network.named_parameters())[name] for network in self.networks] for name in names]
        self.stacked: list[th.Tensor] = []
        self.grads: list[th.Tensor] = []
        # Every member parameter, and the addresses of their storage (and gradients') where `link` put them.
        self._parameters = [parameter for members in self.members for parameter in members]
        self._addresses: list[int] = []
        self._grad_addresses: list[int] = []
        index = {name: k for k, name in enumerate(names)}
        self.plans: list[list[_Layer]] = []
        for prefix, sequence in zip(self._prefixes(first), _sequences(first), strict=True):
            plan: list[_Layer] = []
            for position, module in enumerate(sequence):
                if isinstance(module, nn.Linear):
                    path = f"{prefix}{position}." if prefix != "heads." else prefix
                    plan.append((index[f"{path}weight"], index[f"{path}bias"]))
                else:
                    plan.append(module)
            self.plans.append(plan)
        self.link()

    @staticmethod
    def _prefixes(network: LegendreAdvantageNetwork) -> list[str]:
        return ["trunk.", "heads."] if network.fused_heads else ["trunk.", "value_head.", "coefficient_head."]

    def is_current(self) -> bool:
        """
        A quick check that the stacks are still the networks' (the first parameter of the first network is the first
        row of its stack), for calls between :meth:`link` calls; :meth:`is_linked` checks every parameter.
        """
        return bool(self.stacked) and self.members[0][0].data_ptr() == self.stacked[0].data_ptr()

    def is_linked(self) -> bool:
        """Whether every network's parameter (and, with ``requires_grad``, its gradient) is a view of its stack."""
        # The addresses recorded by `link` (rows of the stacks, which only this object holds, so their memory is
        # never reused): one comparison of two lists, where recomputing them from the stacks cost a tenth of a step.
        if not self.stacked or [parameter.data_ptr() for parameter in self._parameters] != self._addresses:
            return False
        if self.requires_grad:
            grads = [parameter.grad for parameter in self._parameters]
            return [-1 if grad is None else grad.data_ptr() for grad in grads] == self._grad_addresses
        return True

    def link(self) -> None:
        """
        Make the networks' parameters (and gradients) views of stacked tensors, unless they are already: the stacks
        are built from the parameters' current values.
        """
        if self.is_linked():
            return
        self.stacked, self.grads = [], []
        for members in self.members:
            stacked = th.stack([parameter.detach() for parameter in members])
            for i, parameter in enumerate(members):
                # `.data` keeps the Parameter object, the optimizer's key and the state dict's entry; only its storage
                # becomes a row of the stack.
                parameter.data = stacked[i]
            if self.requires_grad:
                stacked.requires_grad_(True)
                stacked.grad = th.zeros_like(stacked)
                for i, parameter in enumerate(members):
                    parameter.grad = stacked.grad[i]
                self.grads.append(stacked.grad)
            self.stacked.append(stacked)
        self._addresses = [parameter.data_ptr() for parameter in self._parameters]
        if self.requires_grad:
            self._grad_addresses = [parameter.grad.data_ptr() for parameter in self._parameters]  # type: ignore[union-attr]

    def zero_grad(self) -> None:
        """Zero the stacked gradients in place (the optimizer's ``zero_grad`` would unlink the per-network ones)."""
        th._foreach_zero_(self.grads)

    def _mlp(self, plan: list[_Layer], x: th.Tensor) -> th.Tensor:
        """Apply one stacked MLP: ``x`` is ``(batch, in)``, shared by the networks, or ``(n_critics, batch, in)``."""
        for layer in plan:
            if isinstance(layer, nn.Module):
                x = layer(x)
                continue
            weight, bias = self.stacked[layer[0]], self.stacked[layer[1]]
            if x.dim() == 2:
                # Shared input: one linear layer over the concatenated weights, then split by critic.
                out = F.linear(x, weight.flatten(0, 1), bias.flatten())
                x = out.view(x.shape[0], weight.shape[0], weight.shape[1]).transpose(0, 1)
            else:
                x = th.baddbmm(bias.unsqueeze(1), x, weight.transpose(1, 2))
        return x

    def q_values(self, obs: th.Tensor, actions: th.Tensor) -> th.Tensor:
        """
        ``Q_i(s, a)`` of every network, as the critic's ``forward`` computes them one by one
        (:meth:`~sb3_adc.adc.legendre.LegendreAdvantageNetwork.q_value` with mean aggregation).

        :param obs: Observations
        :param actions: Scaled actions ``(batch, action_dim)``
        :return: ``(n_critics, batch, 1)``
        """
        critic = self.critic
        with th.set_grad_enabled(not critic.share_features_extractor and th.is_grad_enabled()):
            features = critic.extract_features(obs, critic.features_extractor)
        first = self.networks[0]
        hidden = self._mlp(self.plans[0], features)
        if first.fused_heads:
            outputs = self._mlp(self.plans[1], hidden)
            if first.monomials:
                powers = F.pad(actions.unsqueeze(-1).pow(first.exponents).flatten(1), (1, 0), value=1.0)
                return (outputs * (powers @ first.q_weight_matrix)).sum(dim=-1, keepdim=True)
            value, coefficients = outputs[..., :1], outputs[..., 1:]
        else:
            value, coefficients = self._mlp(self.plans[1], hidden), self._mlp(self.plans[2], hidden)
        return value + (coefficients * first.centred_basis(actions).flatten(1)).sum(dim=-1, keepdim=True)

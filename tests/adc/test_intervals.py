"""The interval partition and the aggregation of the dueling critic (ADC paper, Eq. 11-14)."""

import pytest
import torch as th

from sb3_adc.adc.intervals import MAX_N_INTERVALS, UniformIntervalPartition, aggregate, validate_interval_options


@pytest.mark.parametrize("n_intervals", [2, 7, 100])
def test_range_ends_fall_in_first_and_last_interval(n_intervals):
    partition = UniformIntervalPartition(n_intervals)
    index = partition.index(th.tensor([-1.0, 1.0]))
    assert index.tolist() == [0, n_intervals - 1]


@pytest.mark.parametrize("n_intervals", [2, 5, 100])
def test_each_inner_edge_opens_its_interval(n_intervals):
    partition = UniformIntervalPartition(n_intervals)
    edges = partition.edges
    inner = edges[1:-1]
    # An edge belongs to the interval it opens; the float just below it to the previous interval.
    assert partition.index(inner).tolist() == list(range(1, n_intervals))
    below = th.nextafter(inner, th.full_like(inner, -2.0))
    assert partition.index(below).tolist() == list(range(0, n_intervals - 1))


def test_edges_are_uniform_over_scaled_action_range():
    partition = UniformIntervalPartition(4)
    assert partition.edges.tolist() == pytest.approx([-1.0, -0.5, 0.0, 0.5, 1.0])
    assert partition.centres.tolist() == pytest.approx([-0.75, -0.25, 0.25, 0.75])
    # Every centre lies inside its own interval.
    assert partition.index(partition.centres).tolist() == [0, 1, 2, 3]


def test_actions_outside_range_clamp_to_end_intervals():
    partition = UniformIntervalPartition(10)
    assert partition.index(th.tensor([-3.0, 3.0])).tolist() == [0, 9]


def test_index_keeps_batch_shape():
    partition = UniformIntervalPartition(10)
    actions = th.rand(6, 3) * 2 - 1
    index = partition.index(actions)
    assert index.shape == (6, 3)
    assert index.dtype == th.int64


def test_select_none_reads_the_containing_interval():
    partition = UniformIntervalPartition(4)
    advantages = th.tensor([[[10.0, 20.0, 30.0, 40.0]]])  # (batch=1, action_dim=1, n=4)
    for action, expected in [(-1.0, 10.0), (-0.6, 10.0), (-0.5, 20.0), (0.1, 30.0), (0.99, 40.0), (1.0, 40.0)]:
        selected = partition.select(advantages, th.tensor([[action]]), "none")
        assert selected.item() == pytest.approx(expected)


def test_select_linear_interpolates_between_centres():
    partition = UniformIntervalPartition(4)  # centres -0.75, -0.25, 0.25, 0.75
    advantages = th.tensor([[[10.0, 20.0, 30.0, 40.0]]])
    cases = [(-0.75, 10.0), (-0.5, 15.0), (-0.25, 20.0), (0.0, 25.0), (0.75, 40.0), (-1.0, 10.0), (1.0, 40.0)]
    for action, expected in cases:
        selected = partition.select(advantages, th.tensor([[action]]), "linear")
        assert selected.item() == pytest.approx(expected)


def test_linear_interpolation_passes_gradient_to_the_action():
    partition = UniformIntervalPartition(4)
    advantages = th.tensor([[[10.0, 20.0, 30.0, 40.0]]])
    action = th.tensor([[0.1]], requires_grad=True)
    partition.select(advantages, action, "linear").sum().backward()
    # Between the centres 0.25 and 0.75 the advantage rises by 10 over 0.5 of action: slope 20.
    assert action.grad is not None
    assert action.grad.item() == pytest.approx(20.0)

    action_none = th.tensor([[0.1]], requires_grad=True)
    selected = partition.select(advantages, action_none, "none")
    assert not selected.requires_grad  # piecewise constant: no gradient through the lookup


def reference_q(value, advantages, actions, aggregation):
    """Eq. 11 / 13-14 written out with an explicit lookup, one branch per action dimension."""
    n = advantages.shape[-1]
    index = th.clamp(((actions + 1) / 2 * n).floor().long(), 0, n - 1)
    selected = advantages.gather(-1, index.unsqueeze(-1)).squeeze(-1)
    baseline = advantages.mean(-1) if aggregation == "mean" else advantages.max(-1).values
    return value + (selected - baseline).sum(-1, keepdim=True)


@pytest.mark.parametrize("aggregation", ["mean", "max"])
@pytest.mark.parametrize("action_dim", [1, 3])
def test_aggregation_matches_the_equations(aggregation, action_dim):
    generator = th.Generator().manual_seed(0)
    batch, n = 6, 7
    partition = UniformIntervalPartition(n)
    value = th.randn(batch, 1, generator=generator)
    advantages = th.randn(batch, action_dim, n, generator=generator)
    actions = th.rand(batch, action_dim, generator=generator) * 2 - 1
    weights = partition.centred_weights(actions, advantages, aggregation, "none")
    th.testing.assert_close(aggregate(value, advantages, weights), reference_q(value, advantages, actions, aggregation))


def q_at_every_centre(aggregation: str) -> tuple[th.Tensor, th.Tensor]:
    """``V`` ``(4, 1)`` and ``Q(s, z)`` at each of 9 interval centres ``(9, 4, 1)``, for random streams."""
    partition = UniformIntervalPartition(9)
    value = th.randn(4, 1)
    advantages = th.randn(4, 1, 9)
    q_all = th.stack(
        [
            aggregate(value, advantages, partition.centred_weights(th.full((4, 1), c), advantages, aggregation, "none"))
            for c in partition.centres
        ]
    )
    return value, q_all


def test_mean_aggregation_identity():
    # Eq. 12-14: over the n intervals the centred advantage averages to zero, so mean_z Q(s, z) == V(s).
    value, q_all = q_at_every_centre("mean")
    th.testing.assert_close(q_all.mean(0), value)


def test_max_aggregation_identity():
    # Eq. 11: Q <= V everywhere, with equality at the best interval.
    value, q_all = q_at_every_centre("max")
    assert th.all(q_all <= value + 1e-6)
    th.testing.assert_close(q_all.max(0).values, value)


@pytest.mark.parametrize("aggregation", ["mean", "max"])
@pytest.mark.parametrize("interpolation", ["none", "linear"])
def test_aggregation_is_invariant_to_shifting_advantages(aggregation, interpolation):
    partition = UniformIntervalPartition(5)
    value = th.zeros(2, 1)
    advantages = th.randn(2, 2, 5)
    actions = th.rand(2, 2) * 2 - 1
    q = aggregate(value, advantages, partition.centred_weights(actions, advantages, aggregation, interpolation))
    shifted = advantages + 7.0
    q_shifted = aggregate(value, shifted, partition.centred_weights(actions, shifted, aggregation, interpolation))
    th.testing.assert_close(q, q_shifted)


def test_linear_interpolation_weights_sum_to_one_and_carry_the_action_gradient():
    partition = UniformIntervalPartition(6)
    actions = (th.rand(10, 2) * 2 - 1).requires_grad_(True)
    weights = partition.selection_weights(actions, "linear")
    th.testing.assert_close(weights.sum(-1), th.ones(10, 2))
    assert th.all(weights >= 0)
    assert weights.requires_grad


def test_max_aggregation_gradient_reaches_the_best_interval():
    partition = UniformIntervalPartition(4)
    advantages = th.tensor([[[0.0, 3.0, 1.0, 2.0]]], requires_grad=True)
    q = aggregate(th.zeros(1, 1), advantages, partition.centred_weights(th.tensor([[0.6]]), advantages, "max", "none"))
    q.sum().backward()
    # Q = A(z=3) - A(z=1): +1 on the action's interval, -1 on the arg max.
    assert advantages.grad.tolist() == [[[0.0, -1.0, 0.0, 1.0]]]


@pytest.mark.parametrize("bad", [1, 0, -3, 2.5, "10", True, None, MAX_N_INTERVALS + 1, 10**5])
def test_invalid_n_intervals_is_rejected(bad):
    with pytest.raises(ValueError, match="n_intervals"):
        validate_interval_options(bad, "mean", "none")
    with pytest.raises(ValueError, match="n_intervals"):
        UniformIntervalPartition(bad)


def test_invalid_aggregation_and_interpolation_list_accepted_values():
    with pytest.raises(ValueError, match=r"aggregation.*'mean', 'max'.*'median'"):
        validate_interval_options(10, "median", "none")
    with pytest.raises(ValueError, match=r"advantage_interpolation.*'none', 'linear'.*'cubic'"):
        validate_interval_options(10, "mean", "cubic")


def test_n_intervals_bound_is_named_in_the_error():
    with pytest.raises(ValueError, match=rf"`n_intervals` must be an integer >= 2 .* and <= {MAX_N_INTERVALS}.*got 100000"):
        UniformIntervalPartition(10**5)


def test_partition_memory_is_linear_in_n_intervals():
    # The weights are written per sample, never read from an n x n table (10**4 intervals used to take 3 GB).
    partition = UniformIntervalPartition(MAX_N_INTERVALS)
    assert sum(buffer.numel() for buffer in partition.buffers()) <= 3 * MAX_N_INTERVALS + 1
    actions = th.tensor([[-1.0], [0.0], [0.99]])
    weights = partition.centred_weights(actions, None, "mean", "none")
    assert weights.shape == (3, 1, MAX_N_INTERVALS)
    index = partition.index(actions).view(-1)
    assert index[0] == 0
    assert index[2] > index[1] > 0
    assert weights[th.arange(3), 0, index].tolist() == pytest.approx([1 - 1 / MAX_N_INTERVALS] * 3)
    assert weights.sum().item() == pytest.approx(0.0, abs=1e-3)  # the centred weights sum to 0


@pytest.mark.parametrize("action_dim", [1, 3])
@pytest.mark.parametrize("interpolation", ["none", "linear"])
@pytest.mark.parametrize("aggregation", ["mean", "max"])
def test_centred_weights_are_those_of_the_equations(action_dim, interpolation, aggregation):
    n = 6
    partition = UniformIntervalPartition(n)
    th.manual_seed(0)
    actions = th.rand(32, action_dim) * 2.2 - 1.1
    advantages = th.randn(32, action_dim, n)
    eye = th.eye(n)
    if interpolation == "none":
        selection = eye[partition.index(actions)]
    else:
        position = ((actions + 1) * n / 2 - 0.5).clamp(0, n - 1)
        lower = position.floor().clamp(max=n - 2).long()
        share = (position - lower).unsqueeze(-1)
        selection = eye[lower] * (1 - share) + eye[lower + 1] * share
    centre = 1.0 / n if aggregation == "mean" else eye[advantages.argmax(dim=-1)]
    expected = selection - centre
    weights = partition.centred_weights(actions, advantages, aggregation, interpolation)
    assert th.allclose(weights, expected, atol=1e-6)
    assert th.allclose(partition.selection_weights(actions, interpolation), selection, atol=1e-6)


def test_weights_follow_the_module_dtype():
    partition = UniformIntervalPartition(5).double()
    actions = th.tensor([[0.3]], dtype=th.float64)
    assert partition.centred_weights(actions, None, "mean", "none").dtype == th.float64

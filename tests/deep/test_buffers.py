"""Replay buffers, the n-step window and the rollout buffer."""

from __future__ import annotations

import numpy as np
import pytest

from policylab.deep.common.buffers import (
    NStepWindow,
    PrioritizedReplayBuffer,
    ReplayBuffer,
    RolloutBuffer,
)
from policylab.exceptions import InvalidArgumentError


def _fill(buf: ReplayBuffer, n: int) -> None:
    x = np.arange(n, dtype=np.float32)[:, None]
    buf.add(x, np.arange(n) % 2, x[:, 0], x + 1, np.full(n, 0.9))


def test_replay_wraps_around_and_samples_stored_transitions() -> None:
    buf = ReplayBuffer(5, (1,), seed=0)
    _fill(buf, 7)
    assert len(buf) == 5
    assert sorted(buf.obs[:, 0].tolist()) == [2.0, 3.0, 4.0, 5.0, 6.0]
    b = buf.sample(64)
    np.testing.assert_array_equal(b.next_obs, b.obs + 1)
    np.testing.assert_array_equal(b.returns, b.obs[:, 0])
    assert set(b.obs[:, 0].tolist()) <= {2.0, 3.0, 4.0, 5.0, 6.0}


def test_replay_same_seed_same_batches() -> None:
    a, b = ReplayBuffer(10, (1,), seed=3), ReplayBuffer(10, (1,), seed=3)
    _fill(a, 10)
    _fill(b, 10)
    np.testing.assert_array_equal(a.sample(8).indices, b.sample(8).indices)


def test_empty_replay_refuses_to_sample() -> None:
    with pytest.raises(InvalidArgumentError, match="empty"):
        ReplayBuffer(3, (1,)).sample(2)


def test_prioritized_sampling_follows_priorities() -> None:
    buf = PrioritizedReplayBuffer(4, (1,), alpha=1.0, eps=0.0, seed=0)
    _fill(buf, 4)
    buf.update_priorities(np.arange(4), np.array([1.0, 2.0, 3.0, 4.0]))
    counts = np.zeros(4)
    for _ in range(200):
        counts += np.bincount(buf.sample(50).indices, minlength=4)
    np.testing.assert_allclose(counts / counts.sum(), [0.1, 0.2, 0.3, 0.4], atol=0.01)
    # importance weights (N P(i))^-beta / max: with beta = 1, w_i = p_min / p_i
    b = buf.sample(16, beta=1.0)
    np.testing.assert_allclose(b.weights, 1.0 / (b.indices + 1), rtol=1e-6)


def test_prioritized_new_transitions_get_max_priority() -> None:
    buf = PrioritizedReplayBuffer(8, (1,), alpha=0.5, seed=0)
    _fill(buf, 2)
    buf.update_priorities(np.array([0, 1]), np.array([9.0, 1.0]))
    _fill(buf, 1)
    leaves = buf.tree[buf.leaves : buf.leaves + 3]
    np.testing.assert_allclose(leaves, np.array([9.0, 1.0, 9.0]) ** 0.5, rtol=1e-5)
    np.testing.assert_allclose(buf.tree[1], leaves.sum())


def test_replay_state_round_trip() -> None:
    buf = PrioritizedReplayBuffer(6, (1,), seed=0)
    _fill(buf, 4)
    buf.update_priorities(np.array([2]), np.array([5.0]))
    other = PrioritizedReplayBuffer(6, (1,), seed=0)
    other.load_state_dict(buf.state_dict())
    np.testing.assert_array_equal(other.obs, buf.obs)
    np.testing.assert_allclose(other.tree, buf.tree)
    assert other.pos == buf.pos and other.max_priority == buf.max_priority


def test_n_step_window_matches_hand_computed_returns() -> None:
    # one env, episode of 4 steps truncated at the end, n = 2, gamma = 0.5
    w = NStepWindow(1, 2, 0.5)
    out = []
    for t, r in enumerate([1.0, 2.0, 3.0, 4.0]):
        res = w.push(
            np.array([[float(t)]]), np.array([0]), np.array([r]), np.array([[t + 1.0]]),
            np.array([False]), np.array([t == 3]), np.array([True]),
        )  # fmt: skip
        if res is not None:
            out.extend(zip(*res, strict=True))
    obs = [o[0] for o, *_ in out]
    rets = [g for _, _, g, _, _ in out]
    nxt = [n[0] for _, _, _, n, _ in out]
    disc = [d for *_, d in out]
    assert obs == [0.0, 1.0, 2.0, 3.0]
    np.testing.assert_allclose(rets, [1 + 0.5 * 2, 2 + 0.5 * 3, 3 + 0.5 * 4, 4.0])
    assert nxt == [2.0, 3.0, 4.0, 4.0]
    np.testing.assert_allclose(disc, [0.25, 0.25, 0.25, 0.5])  # truncation still bootstraps


def test_n_step_window_termination_removes_bootstrap_and_skips_invalid() -> None:
    w = NStepWindow(2, 3, 0.9)
    res = w.push(
        np.array([[0.0], [10.0]]), np.array([0, 1]), np.array([1.0, 5.0]),
        np.array([[1.0], [11.0]]),
        np.array([True, False]), np.array([False, False]), np.array([True, False]),
    )  # fmt: skip
    assert res is not None
    obs, _, ret, _, disc = res
    assert obs.tolist() == [[0.0]] and ret.tolist() == [1.0] and disc.tolist() == [0.0]
    assert len(w.windows[1]) == 0  # the invalid (reset) step of env 1 was not stored


def test_rollout_minibatches_cover_valid_steps_once() -> None:
    buf = RolloutBuffer(4, 2, (1,), ())
    for t in range(4):
        valid = np.array([True, t != 2])
        buf.add(np.full((2, 1), t), np.zeros(2), np.zeros(2), np.zeros(2), valid)
        buf.add_outcome(np.ones(2), np.zeros(2, bool), np.zeros(2, bool))
    assert buf.full
    idx = np.concatenate(list(buf.minibatches(3, np.random.default_rng(0))))
    assert sorted(idx.tolist()) == [0, 1, 2, 3, 4, 6, 7]  # flat index 5 = (t=2, env 1) is invalid


def test_n_step_window_over_many_envs_matches_per_trajectory_targets() -> None:
    from policylab.deep import n_step_targets

    rng = np.random.default_rng(0)
    N, T, n, g = 3, 40, 3, 0.9
    rewards = rng.normal(size=(T, N))
    term = rng.random((T, N)) < 0.1
    trunc = ~term & (rng.random((T, N)) < 0.1)
    w = NStepWindow(N, n, g)
    got: dict[tuple[int, int], tuple[float, float, float]] = {}
    valid = np.ones(N, dtype=bool)
    for t in range(T):
        obs = np.stack([np.array([t, i], dtype=np.float32) for i in range(N)])
        nxt = obs + np.array([1, 0], dtype=np.float32)
        res = w.push(obs, np.zeros(N, int), rewards[t], nxt, term[t], trunc[t], valid)
        if res is not None:
            for o, _, ret, no, d in zip(*res, strict=True):
                got[(int(o[0]), int(o[1]))] = (float(ret), float(d), float(no[0]))
        valid = ~(term[t] | trunc[t])  # the next step of an env that ended is an autoreset step
    for i in range(N):
        # the same env's steps with the autoreset steps removed, as one trajectory
        steps = [t for t in range(T) if t == 0 or not (term[t - 1, i] or trunc[t - 1, i])]
        ret, disc, last = n_step_targets(rewards[steps, i], term[steps, i], trunc[steps, i], g, n)
        for k, t in enumerate(steps):
            complete = (
                last[k] < len(steps) - 1
                or term[steps[last[k]], i]
                or trunc[steps[last[k]], i]
                or (last[k] - k + 1 == n)
            )
            if not complete:
                continue
            assert got[(t, i)][0] == pytest.approx(ret[k])
            assert got[(t, i)][1] == pytest.approx(disc[k])
            assert got[(t, i)][2] == steps[last[k]] + 1

"""Where policylab's TD3 and Stable-Baselines3's could differ, measured on HalfCheetah-v5.

Checks behind the TD3 row of the 200k-step quality table (BENCHMARKS.md):

``--update``: the same weights loaded into both libraries' TD3 (400x300, the zoo's
settings), the same random minibatches fed to two updates of each, target smoothing
noise 0 so that both compute the same targets. Prints the relative difference
||g_SB3 - c g_policylab|| / ||g_SB3|| of each layer's gradient: the critics' at the first
update (c = 2: policylab's critic loss is sum_i E[(Q_i - y)^2] / 2, SB3's the sum of the
two mean squared errors; Adam's step does not see the factor), and the actor's at the
second (c = 1), with both libraries' critic optimizers switched off so that the actor's
gradient is taken through identical critics.

``--trajectory --steps N``: the same two TD3s (no target smoothing) trained for N updates
on one stream of minibatches drawn from 20,000 steps of random play, with a third, SB3
again with its critics' weights scaled by 1 + 1e-6, as the control: prints how far
policylab's weights and the control's have moved from SB3's. Training is chaotic (a
difference in the last float place grows to tens of per cent in a thousand updates), so
a different algorithm shows as drift beyond the control's, not as drift.

``--gait FILE...``: each saved final policy (``bench_continuous.py --quality ...
--save-dir DIR``; policylab's ``.pt``, SB3's ``.zip``) run for one greedy episode: its
return, mean forward velocity, mean cos of the torso's pitch (1 upright, -1 on its back)
and the share of steps upside down, to tell a flipped gait from a slow upright one.

``--data``: 2,100 steps of policylab's TD3 (the last 100 learning), each stored
transition replayed from its own state (MuJoCo's ``set_state``) to compare rewards and
next observations; then two updates, checking the targets' Polyak step.

``--init {orthogonal,torch} --seed S --steps N``: policylab's TD3 with the zoo's
settings, its actor and critics initialised either as policylab does (orthogonal
weights, zero biases) or as PyTorch's ``nn.Linear`` does (weights and biases uniform in
+-1/sqrt(fan_in): what SB3 and Fujimoto et al. 2018 use), evaluated on 5 greedy episodes
every 20,000 steps, each time with a probe of the actor's saturation and the critic's
values (see ``_Curve``); one JSON line per run is appended to ``--results``.

``--gap``: from the stored results (``benchmarks/results``), the table of the 200k
curves with their probes at 200k, and exact one-sided permutation tests of SB3's mean
return above policylab's (the quality table's seeds, then with the curves' 200k points);
these are read again as runs are added, so last the test planned in advance
(``bench_continuous.TD3_CHEETAH_PLAN``: seeds 16 to 35 of both libraries), or how many
of its runs are still out.

``--sb3-curve --seed S --steps N``: the same learning curve of SB3's TD3, trained as in
the quality table (``bench_continuous._sb3_model``).

    python benchmarks/diag_td3.py --update
    python benchmarks/diag_td3.py --trajectory --steps 1000
    taskset -c 1 python benchmarks/diag_td3.py --sb3-curve --seed 0 --steps 200000 \
        --results benchmarks/results/td3-curves-200k.jsonl
    taskset -c 0 python benchmarks/diag_td3.py --init torch --seed 0 --steps 100000 \
        --results benchmarks/results/td3-curves-100k.jsonl
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np
import torch

import policylab as pl
from policylab.deep.common.buffers import ReplayBatch

ENV_ID = "HalfCheetah-v5"


def _linears(net: torch.nn.Module) -> list[torch.nn.Linear]:
    return [m for m in net.modules() if isinstance(m, torch.nn.Linear)]


def _critic_layers(
    critic: Any, k: int, grads: bool = False
) -> list[tuple[torch.Tensor, torch.Tensor]]:
    """Critic k of policylab's twin critics as (W of shape (in, out), b) per layer.

    The first layer's W is the concatenation of the observation and action blocks;
    ``grads``: their gradients instead.
    """
    ws, bs = list(critic.weights), list(critic.biases)
    if grads:
        ws, bs = [w.grad for w in ws], [b.grad for b in bs]
    layers = [(torch.cat([ws[0][k], ws[1][k]], 0), bs[0][k, 0])]
    layers += [(ws[i + 1][k], bs[i][k, 0]) for i in range(1, len(bs))]
    return layers


def _set_critic(critic: Any, k: int, linears: list[torch.nn.Linear], obs_dim: int) -> None:
    ws, bs = list(critic.weights), list(critic.biases)
    ws[0][k].copy_(linears[0].weight.T[:obs_dim])
    ws[1][k].copy_(linears[0].weight.T[obs_dim:])
    bs[0][k, 0].copy_(linears[0].bias)
    for i in range(1, len(linears)):
        ws[i + 1][k].copy_(linears[i].weight.T)
        bs[i][k, 0].copy_(linears[i].bias)


def _rel(a: torch.Tensor, b: torch.Tensor) -> float:
    return float((a - b).norm() / a.norm())


_TWIN_KW: dict[str, Any] = dict(learning_rate=1e-3, target_policy_noise=0.0)


def _sb3_td3() -> Any:
    from stable_baselines3 import TD3 as SB3TD3
    from stable_baselines3.common.logger import configure

    sb = SB3TD3(
        "MlpPolicy", ENV_ID, policy_kwargs=dict(net_arch=[400, 300]), device="cpu", seed=0,
        **_TWIN_KW,
    )  # fmt: skip
    sb.set_logger(configure(None, []))
    return sb


def _twins() -> tuple[Any, Any]:
    """policylab's TD3 and SB3's (400x300, lr 1e-3, no target smoothing), SB3's weights in both."""
    pol = pl.deep.TD3(ENV_ID, seed=0, hidden=(400, 300), learning_starts=10, **_TWIN_KW)
    sb = _sb3_td3()
    with torch.no_grad():
        for src, dst in ((sb.actor.mu, pol.actor.net), (sb.actor_target.mu, pol.actor_target.net)):
            for s, d in zip(_linears(src), _linears(dst), strict=True):
                d.weight.copy_(s.weight)
                d.bias.copy_(s.bias)
        for src_critic, dst_critic in (
            (sb.critic, pol.critic),
            (sb.critic_target, pol.critic_target),
        ):
            for k, q_net in enumerate(src_critic.q_networks):
                _set_critic(dst_critic, k, _linears(q_net), pol.obs_dim)
    return pol, sb


def _sb3_train_on(sb: Any, o: Any, a: Any, r: Any, o2: Any, done: Any) -> None:
    """One SB3 TD3 update on this minibatch (its replay buffer's sampler replaced)."""
    from stable_baselines3.common.type_aliases import ReplayBufferSamples

    samples = ReplayBufferSamples(
        *(torch.as_tensor(x) for x in (o, a, o2)),
        torch.as_tensor(done)[:, None],
        torch.as_tensor(r)[:, None],
    )
    sb.replay_buffer.sample = lambda *_, s=samples, **__: s
    sb.train(gradient_steps=1, batch_size=len(o))


def _pl_train_on(pol: Any, o: Any, a: Any, r: Any, o2: Any, done: Any) -> None:
    """One policylab TD3 update on this minibatch."""
    n = len(o)
    pol._train_step(
        ReplayBatch(
            indices=np.arange(n),
            obs=o,
            actions=a,
            returns=r,
            next_obs=o2,
            discounts=(0.99 * (1 - done)).astype(np.float32),
            weights=np.ones(n, np.float32),
        )
    )


def update(args: argparse.Namespace) -> None:
    """Both libraries' TD3 from the same weights on the same minibatches: gradients."""
    torch.set_num_threads(1)
    pol, sb = _twins()
    obs_dim, m = pol.obs_dim, pol.action_dim
    rng = np.random.default_rng(args.seed)
    batch_size = 256
    for step in (1, 2):
        o = rng.normal(size=(batch_size, obs_dim)).astype(np.float32)
        a = rng.uniform(-1, 1, (batch_size, m)).astype(np.float32)
        r = rng.normal(size=batch_size).astype(np.float32)
        o2 = rng.normal(size=(batch_size, obs_dim)).astype(np.float32)
        done = (rng.uniform(size=batch_size) < 0.1).astype(np.float32)
        _sb3_train_on(sb, o, a, r, o2, done)
        _pl_train_on(pol, o, a, r, o2, done)
        if step == 1:
            print("update 1, critics: ||g_SB3 - 2 g_policylab|| / ||g_SB3|| per layer (W, b)")
            for k, q_net in enumerate(sb.critic.q_networks):
                for i, (lin, (w, b)) in enumerate(
                    zip(_linears(q_net), _critic_layers(pol.critic, k, grads=True), strict=True)
                ):
                    print(
                        f"  critic {k + 1} layer {i + 1}: {_rel(lin.weight.grad.T, 2 * w):.1e}, "
                        f"{_rel(lin.bias.grad, 2 * b):.1e}"
                    )
            # identical critics for the actor step of update 2: both critic optimizers off
            sb.critic.optimizer.step = lambda *_, **__: None  # type: ignore[method-assign]
            for group in pol.critic_optimizer.param_groups:
                group["lr"] = 0.0
            with torch.no_grad():
                for k, q_net in enumerate(sb.critic.q_networks):
                    _set_critic(pol.critic, k, _linears(q_net), obs_dim)
    print("update 2, actor: ||g_SB3 - g_policylab|| / ||g_SB3|| per layer (W, b)")
    for i, (s, d) in enumerate(zip(_linears(sb.actor.mu), _linears(pol.actor.net), strict=True)):
        print(
            f"  actor layer {i + 1}: {_rel(s.weight.grad, d.weight.grad):.1e}, "
            f"{_rel(s.bias.grad, d.bias.grad):.1e}"
        )


def _weights(agent: Any) -> dict[str, list[torch.Tensor]]:
    """Each network's weight matrices, as (in, out) for the critics, whichever library."""
    if isinstance(agent, pl.deep.TD3):
        return {
            "actor": [lin.weight for lin in _linears(agent.actor.net)],
            "actor target": [lin.weight for lin in _linears(agent.actor_target.net)],
            "critics": [w for k in range(2) for w, _ in _critic_layers(agent.critic, k)],
            "critic targets": [
                w for k in range(2) for w, _ in _critic_layers(agent.critic_target, k)
            ],
        }
    return {
        "actor": [lin.weight for lin in _linears(agent.actor.mu)],
        "actor target": [lin.weight for lin in _linears(agent.actor_target.mu)],
        "critics": [lin.weight.T for q in agent.critic.q_networks for lin in _linears(q)],
        "critic targets": [
            lin.weight.T for q in agent.critic_target.q_networks for lin in _linears(q)
        ],
    }


def _drift(a: Any, b: Any) -> dict[str, float]:
    """||W_a - W_b|| / ||W_a|| over each network's weight matrices."""
    wa, wb = _weights(a), _weights(b)
    out = {}
    for name in wa:
        num = sum(
            float((x - y).detach().norm() ** 2) for x, y in zip(wa[name], wb[name], strict=True)
        )
        den = sum(float(x.detach().norm() ** 2) for x in wa[name])
        out[name] = (num / den) ** 0.5
    return out


def trajectory(args: argparse.Namespace) -> None:
    """Both TD3s trained on the same stream of minibatches; SB3 against itself as control."""
    torch.set_num_threads(1)
    pol, sb = _twins()
    control = _sb3_td3()
    control.set_parameters(sb.get_parameters())
    with torch.no_grad():  # SB3 again, its critics' weights off by one part in a million
        for p in control.critic.parameters():
            p.mul_(1 + 1e-6)
    # 20,000 steps of uniformly random play (the warm-up's data); the time limit truncates
    env = gym.make(ENV_ID)
    o, _ = env.reset(seed=args.seed)
    rng = np.random.default_rng(args.seed)
    rows: list[tuple[Any, ...]] = []
    for _ in range(20_000):
        a = rng.uniform(-1, 1, pol.action_dim).astype(np.float32)
        o2, r, term, trunc, _ = env.step(a)
        rows.append((o, a, r, o2, float(term)))
        o = env.reset()[0] if term or trunc else o2
    obs, acts, rews, nxt, dones = (np.asarray(c, np.float32) for c in zip(*rows, strict=True))
    print(
        f"{args.steps:,} updates on minibatches of 256 from 20,000 random steps: "
        "||W_a - W_b|| / ||W_a|| per network"
    )
    print("| updates | pair | actor | actor target | critics | critic targets |")
    print("|---:|---|---:|---:|---:|---:|")
    for step in range(1, args.steps + 1):
        i = rng.integers(0, len(obs), 256)
        batch = (obs[i], acts[i], rews[i], nxt[i], dones[i])
        _sb3_train_on(sb, *batch)
        _sb3_train_on(control, *batch)
        _pl_train_on(pol, *batch)
        if step in (1, 2, 10, 100) or step % 500 == 0:
            for label, other in (("SB3, policylab", pol), ("SB3, SB3 x (1 + 1e-6)", control)):
                d = _drift(sb, other)
                print(
                    f"| {step:,} | {label} | " + " | ".join(f"{v:.1e}" for v in d.values()) + " |"
                )


def data(args: argparse.Namespace) -> None:
    """A real run's stored transitions, replayed through MuJoCo, and its Polyak step."""
    torch.set_num_threads(1)
    agent = pl.deep.TD3(ENV_ID, seed=args.seed, hidden=(400, 300), learning_starts=2_000)
    agent.learn(2_100)
    rb, n = agent.replay, agent.replay.size
    env = gym.make(ENV_ID)
    env.reset(seed=0)
    sim = env.unwrapped
    reward_err = obs_err = 0.0
    for i in range(n):  # HalfCheetah's observation is qpos[1:] then qvel; rootx is free
        sim.set_state(np.concatenate([[0.0], rb.obs[i][:8]]), rb.obs[i][8:].astype(np.float64))
        nxt, reward, *_ = env.step(rb.actions[i])  # the action bounds are [-1, 1]
        reward_err = max(reward_err, abs(reward - rb.returns[i]))
        obs_err = max(obs_err, float(np.abs(nxt - rb.next_obs[i]).max()))
    breaks = np.nonzero(np.abs(rb.next_obs[: n - 1] - rb.obs[1:n]).max(axis=1) > 1e-6)[0]
    print(
        f"{n} transitions: max |reward error| {reward_err:.1e}, max |next obs error| "
        f"{obs_err:.1e}, discounts {np.unique(rb.discounts[:n])}, breaks after {breaks}"
    )
    batch = rb.sample(256)
    for _ in range(2):  # one of the two updates steps the actor and both targets
        before = [
            torch.cat([p.reshape(-1) for p in ps]).clone()
            for ps in (agent._target_params, agent._actor_target_params)
        ]
        agent._train_step(batch)
        for name, old, target, online in zip(
            ("critic", "actor"),
            before,
            (agent._target_params, agent._actor_target_params),
            (agent._critic_params, agent._actor_params),
            strict=True,
        ):
            new, theta = (
                torch.cat([p.detach().reshape(-1) for p in ps]) for ps in (target, online)
            )
            tau = agent.config.tau
            err = float((new - ((1 - tau) * old + tau * theta)).norm())
            print(
                f"update {agent.n_updates}, {name} target: moved {float((new - old).norm()):.1e}, "
                f"off (1 - tau) theta' + tau theta by {err:.1e}"
            )


def gait(args: argparse.Namespace) -> None:
    """How each saved final policy runs: upright or on its back (``--save-dir`` files)."""
    from stable_baselines3 import TD3 as SB3TD3

    from bench_continuous import _SB3Predictor

    torch.set_num_threads(1)
    print(
        "| policy | return | mean forward velocity | mean cos(pitch) | share of steps "
        "upside down |\n|---|---:|---:|---:|---:|"
    )
    for path in args.gait:
        policy: Any = (
            _SB3Predictor(SB3TD3.load(path, device="cpu"))
            if path.endswith(".zip")
            else pl.deep.TD3.load(path)
        )
        env = gym.make(ENV_ID)
        obs, _ = env.reset(seed=1000)
        data = env.unwrapped.data
        ret, vx, pitch, done = 0.0, [], [], False
        while not done:
            obs, r, term, trunc, _ = env.step(policy.predict(obs, deterministic=True))
            ret += float(r)
            vx.append(float(data.qvel[0]))  # rootx velocity
            pitch.append(float(data.qpos[2]))  # rooty: 0 upright, +-pi on its back
            done = term or trunc
        c = np.cos(pitch)
        print(
            f"| {Path(path).name} | {ret:.1f} | {np.mean(vx):.2f} | {c.mean():.2f} "
            f"| {np.mean(c < 0):.2f} |"
        )


def _torch_init(agent: Any, seed: int) -> None:
    """Re-initialise the actor, the critics and their targets as ``nn.Linear`` does."""
    torch.manual_seed(seed)
    with torch.no_grad():
        for layer, target_layer in zip(
            _linears(agent.actor.net), _linears(agent.actor_target.net), strict=True
        ):
            fresh = torch.nn.Linear(layer.in_features, layer.out_features)
            for p in (layer, target_layer):
                p.weight.copy_(fresh.weight)
                p.bias.copy_(fresh.bias)
        for k in range(2):
            shapes = [w.shape for w, _ in _critic_layers(agent.critic, k)]
            fresh_layers = [torch.nn.Linear(n_in, n_out) for n_in, n_out in shapes]
            _set_critic(agent.critic, k, fresh_layers, agent.obs_dim)
        for p, target in zip(
            agent.critic.parameters(), agent.critic_target.parameters(), strict=True
        ):
            target.copy_(p)


class _Curve:
    """Greedy returns every 20,000 env steps (5 episodes, reset seed 1000 + seed).

    With each return, a probe of what could drift late in a run, on 1,024 stored
    observations drawn by the probe's own generator (the run's own draws are untouched):
    the share of the actor's action components at |mu(s)| > 0.99, the mean |pre-tanh
    output|, and the mean Q_1(s, mu(s)).
    """

    def __init__(self, label: str, seed: int) -> None:
        self.label, self.seed = label, seed
        self.points: list[tuple[int, float]] = []
        self.probes: list[tuple[int, float, float, float]] = []
        self.rng = np.random.default_rng(seed)
        self.start = time.perf_counter()

    def due(self, steps: int) -> bool:
        return (
            steps > 0 and steps % 20_000 == 0 and (not self.points or self.points[-1][0] != steps)
        )

    def at(self, steps: int, agent: Any, stored_obs: np.ndarray, probe: Any) -> None:
        """Evaluate ``agent``; ``probe(obs)`` gives (pre-tanh outputs, Q_1(s, mu(s)))."""
        ret = float(np.mean(pl.deep.evaluate(agent, ENV_ID, 5, 1000 + self.seed)))
        self.points.append((steps, round(ret, 1)))
        obs = torch.as_tensor(stored_obs[self.rng.integers(0, len(stored_obs), 1024)])
        with torch.no_grad():
            pre, q = probe(obs.float())
        saturated = float((torch.tanh(pre).abs() > 0.99).float().mean())
        size, q_mean = float(pre.abs().mean()), float(q.mean())
        self.probes.append((steps, round(saturated, 4), round(size, 3), round(q_mean, 1)))
        print(
            f"{self.label} seed {self.seed} step {steps}: {ret:.1f} (saturated {saturated:.3f}, "
            f"|pre-tanh| {size:.2f}, Q {q_mean:.1f}; "
            f"{time.perf_counter() - self.start:.0f} s)",
            flush=True,
        )

    def write(self, path: str | None, **fields: Any) -> None:
        if path:
            line = dict(env=ENV_ID, **fields, seed=self.seed, curve=self.points, probe=self.probes)
            with open(path, "a") as f:
                f.write(json.dumps(line) + "\n")


def init(args: argparse.Namespace) -> None:
    """policylab's TD3 with one of two initialisations: its learning curve."""
    torch.set_num_threads(1)
    fields, _ = pl.deep.default_config("td3", ENV_ID)
    agent = pl.deep.TD3(ENV_ID, seed=args.seed, **fields)
    if args.init == "torch":
        _torch_init(agent, args.seed)
    curve = _Curve(args.init, args.seed)

    def probe(obs: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        pre = agent.actor.features(obs)
        return pre, agent.critic(obs, torch.tanh(pre))[0]

    def every_step(a: Any, _metrics: Any) -> bool:
        if curve.due(a.num_timesteps):
            curve.at(a.num_timesteps, a, a.replay.obs[: a.replay.size], probe)
        return True

    agent.learn(args.steps, callback=every_step)
    curve.write(args.results, lib="policylab", init=args.init)


def sb3_curve(args: argparse.Namespace) -> None:
    """SB3's TD3 with the same settings as the quality table's: its learning curve."""
    from stable_baselines3.common.callbacks import BaseCallback

    from bench_continuous import _sb3_model, _SB3Predictor

    torch.set_num_threads(1)
    curve = _Curve("SB3", args.seed)

    class EveryStep(BaseCallback):  # type: ignore[misc]
        def _on_step(self) -> bool:
            if curve.due(self.num_timesteps):
                model, buffer = self.model, self.model.replay_buffer
                actor, critic = model.actor, model.critic

                def probe(obs: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
                    pre = actor.mu[:-1](obs)  # the actor's MLP before its final Tanh
                    return pre, critic.q1_forward(obs, torch.tanh(pre))[:, 0]

                stored = buffer.observations[: buffer.size(), 0]
                curve.at(self.num_timesteps, _SB3Predictor(model), stored, probe)
            return True

    _sb3_model("td3", ENV_ID, args.seed, args.steps, callback=EveryStep())
    curve.write(args.results, lib="SB3", init="torch")


def gap(args: argparse.Namespace) -> None:
    """The 200k curves' table and the permutation tests of the TD3 gap, from stored results."""
    from bench_continuous import (
        PERMUTATION_RESAMPLES,
        TD3_CHEETAH_PLAN,
        difference_ci,
        permutation_p,
        read_records,
        read_runs,
    )

    results = Path(__file__).parent / "results"
    curves = [json.loads(x) for x in (results / "td3-curves-200k.jsonl").read_text().splitlines()]
    print(
        "| run | seed | 40k | 80k | 120k | 160k | 200k | share saturated | mean abs(pre-tanh) "
        "| mean Q_1(s, mu(s)) |\n|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|"
    )
    for r in sorted(curves, key=lambda r: (r["lib"], r["seed"])):
        at = dict(r["curve"])
        saturated, pre, q = {s: rest for s, *rest in r["probe"]}[200_000]
        init = {"torch": "PyTorch's", "orthogonal": "orthogonal"}[r["init"]]
        name = "SB3" if r["lib"] == "SB3" else f"policylab, {init} init"
        cells = " | ".join(f"{at[k]:.1f}" for k in (40_000, 80_000, 120_000, 160_000, 200_000))
        print(f"| {name} | {r['seed']} | {cells} | {saturated:.2f} | {pre:.2f} | {q:.1f} |")
    runs = read_runs([results / "quality-200k.jsonl"])
    table = {
        k: [round(x, 1) for x in runs[ENV_ID, "TD3", k, 200_000]] for k in ("policylab", "SB3")
    }
    ends = {k: [dict(r["curve"])[200_000] for r in curves if r["lib"] == k] for k in table}
    sb3_all, ours_all = table["SB3"] + ends["SB3"], table["policylab"] + ends["policylab"]
    for label, sb3, ours in (
        ("the table's seeds", table["SB3"], table["policylab"]),
        ("with SB3's curve seeds", sb3_all, table["policylab"]),
        ("and policylab's curve runs", sb3_all, ours_all),
    ):
        p, exact = permutation_p(sb3, ours)
        how = "" if exact else f" (estimated from {PERMUTATION_RESAMPLES:,} random splits)"
        lo, hi = difference_ci(ours, sb3)
        print(
            f"{label}: SB3 {np.mean(sb3):.1f} ({len(sb3)}) against policylab {np.mean(ours):.1f} "
            f"({len(ours)}); policylab - SB3 {np.mean(ours) - np.mean(sb3):+.1f}, 95% bootstrap "
            f"interval [{lo:+.1f}, {hi:+.1f}]; {'exact ' if exact else ''}one-sided permutation "
            f"p = {p:.3f}{how}"
        )
    print(TD3_CHEETAH_PLAN.read(read_records([results / "quality-200k.jsonl"])))


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument(
        "--update", action="store_true", help="compare one update's gradients with SB3's"
    )
    p.add_argument("--init", choices=("orthogonal", "torch"), help="learning curve with this init")
    p.add_argument("--data", action="store_true", help="a real run's data and Polyak step")
    p.add_argument(
        "--trajectory", action="store_true",
        help="--steps updates of both on the same minibatches, against SB3's own drift",
    )  # fmt: skip
    p.add_argument("--sb3-curve", action="store_true", help="SB3's TD3 learning curve")
    p.add_argument(
        "--gap", action="store_true", help="the 200k curves' table and the gap's p-values"
    )
    p.add_argument(
        "--gait", nargs="+", metavar="FILE",
        help="saved final policies (bench_continuous.py --save-dir): upright or flipped",
    )  # fmt: skip
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--steps", type=int, default=100_000)
    p.add_argument("--results", help="append the curve (--init, --sb3-curve) to this file")
    args = p.parse_args()
    if args.update:
        update(args)
    elif args.init:
        init(args)
    elif args.sb3_curve:
        sb3_curve(args)
    elif args.data:
        data(args)
    elif args.trajectory:
        trajectory(args)
    elif args.gait:
        gait(args)
    elif args.gap:
        gap(args)
    else:
        p.error("give --update, --trajectory, --data, --init, --sb3-curve, --gait or --gap")


if __name__ == "__main__":
    main()

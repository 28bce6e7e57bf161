"""Where one DQN env step goes, section by section, at the rl-baselines3-zoo's settings.

One training run of policylab's DQN with the zoo's hyperparameters exactly (the
settings of ``bench_deep.py --per-step``: vanilla DQN, one env, for Acrobot-v1 a
256x256 ReLU network, batch 128, one gradient step per env step), one torch thread,
with the thread CPU time (``time.thread_time``: time spent waiting for a core is not
counted) of each section summed over the run: the gradient step's forward and backward
passes, the Adam step and the norm clip, the target values, the minibatch draw, the
env step, the epsilon-greedy action, and the buffers. Each timed call adds about half
a microsecond. Microseconds per env step, and the share of the run.

Run: ``taskset -c 1 python benchmarks/profile_dqn_step.py [--env Acrobot-v1] [--steps 4000]``.
"""

from __future__ import annotations

import argparse
import collections
import os
import sys
import time
from collections.abc import Callable
from typing import Any

os.environ.setdefault("OMP_NUM_THREADS", "1")

import torch

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))

import bench_deep
import policylab.deep.dqn.agent as dqn_agent
from policylab.deep.common.mlp_grad import ChainPasses


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--env", default="Acrobot-v1", help="Gymnasium id (default Acrobot-v1)")
    ap.add_argument("--steps", type=int, default=4000, help="env steps (default 4,000)")
    args = ap.parse_args()
    torch.set_num_threads(1)
    seconds: collections.Counter[str] = collections.Counter()
    calls: collections.Counter[str] = collections.Counter()

    def timed(name: str, f: Callable[..., Any]) -> Callable[..., Any]:
        def g(*a: Any, **k: Any) -> Any:
            t = time.thread_time()
            out = f(*a, **k)
            seconds[name] += time.thread_time() - t
            calls[name] += 1
            return out

        return g

    agent = bench_deep._make_policylab("dqn", args.env, 0)
    # the gradient step's pieces (module and class attributes, looked up at each call)
    setattr(ChainPasses, "forward", timed("forward pass", ChainPasses.forward))  # noqa: B010
    setattr(ChainPasses, "backward", timed("backward pass", ChainPasses.backward))  # noqa: B010
    dqn_agent.fused_adam_step = timed("Adam step", dqn_agent.fused_adam_step)
    flat = agent._flat
    assert flat is not None, "this profile needs the hand-written update (a plain MLP)"
    flat.clip_grad_norm_ = timed("norm clip", flat.clip_grad_norm_)  # type: ignore[method-assign]
    for attr, name in (
        ("_train_steps_by_hand", "update (all)"),
        ("_next_target_q", "target values"),
        ("_env_step", "env step"),
        ("_epsilon_greedy", "epsilon-greedy action"),
    ):
        setattr(agent, attr, timed(name, getattr(agent, attr)))
    agent.replay.sample = timed("minibatch draw", agent.replay.sample)  # type: ignore[method-assign]
    agent.replay.add = timed("replay add", agent.replay.add)  # type: ignore[method-assign]
    agent.window.push = timed("n-step window", agent.window.push)  # type: ignore[method-assign]
    t0 = time.thread_time()
    agent.learn(args.steps)
    total = time.thread_time() - t0
    steps = agent.num_timesteps
    print(
        f"DQN {args.env}, zoo settings, {steps:,} env steps: {steps / total:,.0f} per "
        f"CPU-second, {1e6 * total / steps:.0f} us each; load average "
        f"{os.getloadavg()[0]:.1f}\n"
    )
    print("| section | us per env step | share | calls |")
    print("|---|---:|---:|---:|")
    for name, s in sorted(seconds.items(), key=lambda kv: -kv[1]):
        print(f"| {name} | {1e6 * s / steps:.1f} | {100 * s / total:.1f}% | {calls[name]:,} |")


if __name__ == "__main__":
    main()

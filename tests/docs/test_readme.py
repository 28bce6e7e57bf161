"""Every Python block of the README runs, what its comments claim holds, and its cheap
shell commands exit 0.

The README shows full budgets (500,000 Blackjack episodes, 100,000 PPO steps); the test
runs the same code with the budgets below, and fails if a budget it replaces is gone from
the README (so the list cannot go stale).
"""

from __future__ import annotations

import re
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from tests.docs._load import ROOT, runpages

import policylab as pl

rp = runpages()
README = (ROOT / "README.md").read_text(encoding="utf-8")
BLOCKS = [b for b in rp.extract_blocks(README) if b.lang == "python"]

#: Per block (found by a line it contains): smaller budgets for the test.
BUDGETS: dict[str, dict[str, str]] = {
    "mc_off_policy(": {"episodes=500_000": "episodes=50_000", "episodes=50_000": "episodes=5_000"},
    "pl.deep.PPO(": {
        "agent.learn(steps,": "agent.learn(2_048,",
        "agent.learn(150_000,": "agent.learn(4_096,",
        "episodes=100": "episodes=5",
    },
    # 100 random steps, then an update a step once the buffer holds a batch of 256: 245
    # updates, the whole loop, not the 20,000 steps of a result
    "pl.deep.SAC(": {"agent.learn(20_000,": "agent.learn(500,"},
}


def _claims_tour(ns: dict[str, Any]) -> None:
    robot, episode = ns["robot"], ns["episode"]
    assert robot.available_actions("high") == ["search", "wait"]
    assert robot.p("high", 4.0, "high", "search") == 0.7
    assert str(episode).startswith("(2, 0), right, -1.0, (2, 1), up, -3.0")
    assert episode.ret(gamma=1.0) == -6
    assert pl.discounted_return([1, 2, 3], 0.5) == 2.75
    assert pl.returns_to_go([-1, -1, -1, 10], 1.0).tolist() == [7, 8, 9, 10]
    assert ns["info"]["action_mask"].tolist() == [1, 1, 1, 1]


def _claims_planning(ns: dict[str, Any]) -> None:
    robot = ns["robot"]
    assert np.allclose(pl.evaluate_policy(robot, ns["det"]), [31.496, 28.346], atol=1e-3)
    assert pl.compare_policies(robot, ns["det"], ns["sto"]) == "better"
    assert ns["res"].error_bound is None or ns["res"].error_bound <= 1e-8
    assert abs(pl.relative_value_iteration(robot).gain - 3.0769) < 1e-4


def _claims_td(ns: dict[str, Any]) -> None:
    assert ns["res"].error["optimal_actions"] == 1.0  # Sarsa on FrozenLake: exact policy
    assert abs(ns["study"].mean_return(100) - (-29)) < 3  # "about -29"


def _claims_deep(ns: dict[str, Any]) -> None:
    assert ns["returns"].shape == (5,)
    assert {"checkpoint.pt", "progress.csv", "run.json", "tb"} <= {
        p.name for p in Path("runs/ppo-cartpole").iterdir()
    }
    assert ns["agent"].num_timesteps >= 4_096
    assert ns["action"] in (0, 1)


def _claims_walking(ns: dict[str, Any]) -> None:
    assert ns["agent"].num_timesteps >= 500 and ns["agent"].n_updates >= 245
    assert ns["walker"].config.learning_starts == 10_000


def _claims_figures(ns: dict[str, Any]) -> None:
    for name in ("bad.png", "q.svg", "path.png", "curves.png", "fig3_5.png"):
        assert Path("runs", name).stat().st_size > 1000, name


CLAIMS = {
    "robot = pl.FiniteMDP.from_dynamics(": _claims_tour,
    "pl.relative_value_iteration(robot).gain": _claims_planning,
    "tabular.seed_study(": _claims_td,
    "pl.deep.PPO(": _claims_deep,
    "pl.deep.SAC(": _claims_walking,
    "plot.save_solution_figure(mdp, v, bad": _claims_figures,
}


def test_the_claims_and_budgets_name_existing_blocks() -> None:
    for marker in [*BUDGETS, *CLAIMS]:
        assert sum(marker in b.code for b in BLOCKS) == 1, f"no single README block has {marker!r}"
    assert len(BLOCKS) >= 6


@pytest.mark.parametrize("block", BLOCKS, ids=[f"line{b.line}" for b in BLOCKS])
def test_readme_block_runs(block: Any, tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    replace = next((r for m, r in BUDGETS.items() if m in block.code), None)
    run = rp.run_blocks([block], f"README.md:{block.line}", workdir=tmp_path, replace=replace)
    assert run.blocks == 1
    check = next((c for m, c in CLAIMS.items() if m in block.code), None)
    if check is not None:
        monkeypatch.chdir(tmp_path)
        check(run.namespace)


#: README shell commands cheap enough to run (in-process, through the command's entry point).
COMMANDS = [
    "policylab --help",
    "policylab problems",
    "policylab show recycling-robot",
    "policylab show FrozenLake-v1 --json",
    "policylab solve gridworld-5x5 --method vi --tol 1e-6",
    "policylab solve FrozenLake-v1 --method lp",
    "policylab evaluate mountain-gridworld --policy bad",
    "policylab evaluate recycling-robot --policy uniform --json",
    "policylab learn mc-prediction slippery-gridworld --every-visit --json",
    "policylab learn mc-control slippery-gridworld --epsilon exp:1,0.999,0.05 --alpha 0.05",
    "policylab learn q-learning cliff-walking --episodes 500 --alpha 0.5 --epsilon 0.1 --seed 0",
    "policylab learn td0 random-walk --episodes 100 --alpha 0.1 --init 0.5",
    "policylab learn double-q-learning maximization-bias --episodes 300 --alpha 0.1",
    "policylab train ppo CartPole-v1 --dry-run",
    "policylab plot values mountain-gridworld --policy bad --out bad.svg",
    "policylab plot q-table slippery-gridworld --policy uniform",
]


@pytest.mark.parametrize("command", COMMANDS)
def test_cheap_readme_command_runs(
    command: str, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    assert command in README, f"{command!r} is no longer in the README"
    monkeypatch.chdir(tmp_path)
    code, output = rp.run_policylab(command.split()[1:])
    assert code == 0, output[-3000:]
    if "--json" in command:
        import json

        assert isinstance(json.loads(output), dict)


def test_readme_links_to_the_documentation_pages() -> None:
    targets = re.findall(r"\]\((docs/[^)]+\.md)\)", README)
    assert "docs/index.md" in targets
    for target in targets:
        assert (ROOT / target).is_file(), f"the README links to {target}, which does not exist"

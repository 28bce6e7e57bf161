"""How the Monte Carlo episode loop is compiled: no reference counting in a step."""

from tests.tabular._machine_code import object_code, reference_count_symbols

import policylab as pl
from policylab import tabular as tab
from policylab.tabular import kernels, mc


def test_the_episode_loops_are_compiled_without_reference_counting():
    assert mc._mc_chunk.targetoptions["_nrt"] is False
    assert kernels.generate_episode.targetoptions["_nrt"] is False


def test_the_episode_loop_has_no_reference_count_operation():
    # Before, about four fifths of a Monte Carlo control step on FrozenLake 8x8 were the
    # atomic reference counts of the row views handed to the action choice. The machine
    # code that runs (compiled here or loaded from the cache) for every signature the
    # learners use.
    tab.mc_control(pl.problems.blackjack(), episodes=5, exploring_starts=True, seed=0)
    tab.mc_prediction(
        pl.problems.gridworld_4x4(),
        policy=pl.Policy.uniform(pl.problems.gridworld_4x4()),
        episodes=5,
        seed=0,
    )
    loop = mc._mc_chunk
    assert loop.signatures
    for sig in loop.signatures:
        obj = object_code(loop, sig)
        # the episode's generation and update are compiled into the loop's module
        assert b"generate_episode" in obj
        assert b"mc_episode_update" in obj
        assert reference_count_symbols(obj) == set()

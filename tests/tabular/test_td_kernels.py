"""How the TD episode loop is compiled: no reference counting in a step."""

import numpy as np
from tests.tabular._machine_code import object_code, reference_count_symbols

import policylab as pl
from policylab import tabular as tab
from policylab.tabular import kernels
from policylab.tabular import td_kernels as tdk


def test_the_episode_loop_is_compiled_without_reference_counting():
    assert tdk.run_kernel.targetoptions["_nrt"] is False


def test_the_episode_loop_has_no_reference_count_operation():
    # Each NRT_incref / NRT_decref is an atomic operation; in the step loop they cost a
    # Q-learning step more than half its time. The machine code that runs (compiled here
    # or loaded from the cache) for the signature the learners use; the module holds
    # every family's episode, each compiled without reference counting too.
    tab.q_learning(pl.problems.cliff_walking(), episodes=2)
    loop = tdk.run_kernel
    obj = object_code(loop, loop.signatures[0])
    for name in ("run_kernel", "one_step_control_episode", "n_step_episode", "lambda_episode"):
        assert name.encode() in obj
    assert reference_count_symbols(obj) == set()


def test_the_reference_count_check_sees_a_function_that_counts():
    """The check above can fail: a kernel that allocates its result counts references."""
    kernels.outcome_cdf(np.array([0, 2], dtype=np.int64), np.array([0.5, 0.5]))
    fn = kernels.outcome_cdf
    assert reference_count_symbols(object_code(fn, fn.signatures[0])) >= {
        "NRT_incref",
        "NRT_decref",
    }

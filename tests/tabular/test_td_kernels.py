"""How the TD episode loop is compiled: no reference counting in a step."""

import numba

import policylab as pl
from policylab import tabular as tab
from policylab.tabular import td_kernels as tdk


def test_the_episode_loop_is_compiled_without_reference_counting():
    assert tdk.run_kernel.targetoptions["_nrt"] is False


def test_the_episode_loop_has_no_reference_count_operation():
    # Each NRT_incref / NRT_decref is an atomic operation; in the step loop they cost a
    # Q-learning step more than half its time. Compiled afresh (cached code cannot be
    # inspected), for the signature the learners use; the module holds every family's
    # episode, each compiled without reference counting too.
    tab.q_learning(pl.problems.cliff_walking(), episodes=2)
    loop = tdk.run_kernel
    opts = {k: v for k, v in loop.targetoptions.items() if k not in ("cache", "nopython")}
    fresh = numba.njit(**opts)(loop.py_func)
    sig = loop.signatures[0]
    fresh.compile(sig)
    llvm = fresh.inspect_llvm(sig)
    for name in ("run_kernel", "one_step_control_episode", "n_step_episode", "lambda_episode"):
        assert name in llvm
    assert "NRT_incref" not in llvm
    assert "NRT_decref" not in llvm

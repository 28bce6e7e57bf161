"""How the TD episode loops are compiled: no reference counting in a step."""

import numba
import pytest

import policylab as pl
from policylab import tabular as tab
from policylab.tabular import td_kernels as tdk


@pytest.mark.parametrize("family", sorted(tdk.KERNELS))
def test_every_loop_is_compiled_without_reference_counting(family):
    assert tdk.KERNELS[family].targetoptions["_nrt"] is False


def test_the_one_step_loop_has_no_reference_count_operation():
    # Each NRT_incref / NRT_decref is an atomic operation; in the step loop they cost a
    # Q-learning step more than half its time. Compiled afresh (cached code cannot be
    # inspected), for the signature the learners use.
    tab.q_learning(pl.problems.cliff_walking(), episodes=2)
    loop = tdk.one_step_control_kernel
    opts = {k: v for k, v in loop.targetoptions.items() if k not in ("cache", "nopython")}
    fresh = numba.njit(**opts)(loop.py_func)
    sig = tdk.run_kernel.signatures[0][1:]  # run_kernel(family, *the loop's arguments)
    fresh.compile(sig)
    llvm = fresh.inspect_llvm(sig)
    assert "define" in llvm and "one_step_control_kernel" in llvm
    assert "NRT_incref" not in llvm
    assert "NRT_decref" not in llvm

"""A sweep across a two-node Ray cluster simulated on this machine (ray.cluster_utils)."""

from __future__ import annotations

import os

import pytest

from policylab.experiments import sweep

ray = pytest.importorskip("ray")


@pytest.fixture(scope="module")
def two_nodes():
    from ray.cluster_utils import Cluster

    os.environ.setdefault("RAY_USAGE_STATS_ENABLED", "0")
    cluster = Cluster(
        initialize_head=True,
        head_node_args={"num_cpus": 1, "include_dashboard": False},
    )
    cluster.add_node(num_cpus=1)
    ray.init(address=cluster.address, log_to_driver=False)
    yield cluster
    ray.shutdown()
    cluster.shutdown()


def test_a_sweep_runs_on_both_nodes(two_nodes, tmp_path, monkeypatch):
    # each trial waits 3 s first, so the second starts on the other node while the first
    # runs (tabular trials reuse their worker, which could otherwise serve them all)
    monkeypatch.setenv("POLICYLAB_SWEEP_TRIAL_DELAY", "3")
    nodes = {n["NodeID"] for n in ray.nodes() if n["Alive"]}
    assert len(nodes) == 2
    doc = sweep(
        "sarsa",
        "cliff-walking",
        seeds=2,
        out=tmp_path / "cl",
        options={"episodes": 400},
        grid={"alpha": [0.1, 0.2, 0.3, 0.4]},
    )
    trials = doc["trials"]
    assert len(trials) == 8 and {t["status"] for t in trials} == {"TERMINATED"}
    used = {t["node_id"] for t in trials}
    assert used == nodes, f"trials ran on {used}, the cluster has {nodes}"

"""Sweeps and tuning on one local Ray (2 CPUs) shared by this module.

Oracles: four sequential `policylab learn` runs (bit-identical tables and returns), an
uninterrupted deep trial (a trial whose worker died must end equal to it), the exact q*
of the planning layer (the score of `tune`), and a trace of every trial's computation
(a killed driver resumed runs each trial exactly once).
"""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from policylab.cli.main import main
from policylab.experiments import resume, sweep, tune

ray = pytest.importorskip("ray")

REPO = Path(__file__).resolve().parents[2]


@pytest.fixture(scope="module", autouse=True)
def local_ray():
    os.environ.setdefault("RAY_USAGE_STATS_ENABLED", "0")
    ray.init(num_cpus=2, include_dashboard=False, log_to_driver=False)
    yield
    ray.shutdown()


def _learn_json(capsys, *argv: str) -> dict:
    with pytest.raises(SystemExit) as exc:
        main(["learn", *argv, "--json"])
        raise SystemExit(0)
    assert exc.value.code in (0, None)
    return json.loads(capsys.readouterr().out)


def _tables(out: Path, trial_id: str) -> dict:
    with np.load(out / "trials" / trial_id / "tables.npz") as z:
        return {k: z[k] for k in z.files}


def test_tabular_sweep_is_bit_identical_to_sequential_learn_runs(tmp_path, capsys):
    out = tmp_path / "sw"
    doc = sweep(
        "q-learning",
        "CliffWalking-v1",
        seeds=4,
        out=out,
        options={"episodes": 120, "epsilon": 0.2},
        grid={"alpha": [0.5]},
    )
    assert doc["kind"] == "policylab-sweep" and doc["command"] == "sweep"
    trials = doc["trials"]
    assert [t["seed"] for t in trials] == [0, 1, 2, 3]
    assert {t["status"] for t in trials} == {"TERMINATED"}
    assert {t["config_label"] for t in trials} == {"default"}  # alpha had one value: fixed
    assert len({t["tune_trial_id"] for t in trials}) == 1  # all seeds in one trial
    tables = _tables(out, trials[0]["tune_trial_id"])
    assert tables["seeds"].tolist() == [0, 1, 2, 3]
    for k, t in enumerate(trials):
        ref = _learn_json(
            capsys, "q-learning", "CliffWalking-v1", "--seed", str(k), "--episodes", "120",
            "--alpha", "0.5", "--epsilon", "0.2",
        )  # fmt: skip
        assert np.array_equal(tables["q"][k], np.asarray(ref["q"]))
        assert np.array_equal(tables["returns"][k], np.asarray(ref["episode_returns"]))
        returns = np.asarray(ref["episode_returns"])
        assert t["metrics"]["score"] == pytest.approx(returns[-12:].mean(), abs=0, rel=1e-12)
        assert t["metrics"]["error_rms"] == pytest.approx(ref["error"]["rms"], rel=1e-12)
        assert t["curve"]["x"][-1] == 120 and len(t["curve"]["y"]) == len(t["curve"]["x"])
    on_disk = json.loads((out / "sweep.json").read_text())
    assert on_disk["trials"] == trials
    assert set(on_disk["statistics"]) == {"default"}
    stat = on_disk["statistics"]["default"]
    scores = np.array([t["metrics"]["score"] for t in trials])
    assert stat["runs"] == 4 and stat["mean"]["value"] == pytest.approx(scores.mean())
    assert stat["iqm"]["low"] <= stat["iqm"]["value"] <= stat["iqm"]["high"]
    # `policylab stats` reads the folder: the same aggregates from the same seeds
    with pytest.raises(SystemExit) as exc:
        main(["stats", str(out), "--json", "--out", str(tmp_path / "figures")])
        raise SystemExit(0)
    assert exc.value.code in (0, None)
    got = json.loads(capsys.readouterr().out)["configs"]["default"]
    assert got["seeds"] == [0, 1, 2, 3]
    assert got["iqm"]["value"] == pytest.approx(stat["iqm"]["value"])


def test_tune_scores_against_the_exact_q_star(tmp_path):
    from policylab.experiments.problems import finite_problem, reachable_states
    from policylab.tabular import q_learning
    from policylab.tabular.truth import GroundTruth

    out = tmp_path / "tu"
    doc = tune(
        "q-learning",
        "CliffWalking-v1",
        trials=3,
        space={"alpha": {"kind": "uniform", "low": 0.1, "high": 0.9}},
        out=out,
        seeds=2,
        options={"episodes": 60},
        search_seed=1,
    )
    assert doc["command"] == "tune" and "q*" in doc["metric_description"]
    assert len({t["tune_trial_id"] for t in doc["trials"]}) == 3
    assert len(doc["trials"]) == 6
    mdp = finite_problem("CliffWalking-v1")
    truth = GroundTruth.control(mdp)
    t = doc["trials"][0]
    res = q_learning(mdp, seed=t["seed"], episodes=60, alpha=t["config"]["alpha"], max_steps=10_000)
    seen = reachable_states(mdp)
    assert seen.sum() == 48 - 10  # CliffWalking: the 10 cliff cells are never entered
    _, rms, _ = truth.errors(res.q, None, seen=seen)
    assert t["metrics"]["score"] == pytest.approx(-rms, rel=1e-12)
    best = doc["best"]
    means = {}
    for x in doc["trials"]:
        means.setdefault(x["config_label"], []).append(x["metrics"]["score"])
    assert best["score"] == pytest.approx(max(np.mean(v) for v in means.values()))


def test_a_deep_trial_whose_worker_dies_resumes_and_ends_equal(tmp_path, monkeypatch):
    """A PPO trial whose worker dies after its first checkpoint is retried from it, and ends
    equal to the same run never interrupted (computed here, without Ray)."""
    from policylab.deep.io import load
    from policylab.experiments.ray_trials import per_seed
    from policylab.experiments.spec import ExperimentSpec
    from policylab.experiments.trials import run_deep

    crash = tmp_path / "crashed"
    monkeypatch.setenv("POLICYLAB_SWEEP_CRASH_ONCE", str(crash))
    out = tmp_path / "deep"
    doc = sweep(
        "ppo",
        "CartPole-v1",
        seeds=[3],
        out=out,
        options={"steps": 1024},
        grid={"checkpoint_every": [512], "torch_threads": [1]},
        max_failures=1,
    )
    assert crash.is_file(), "the crash hook did not fire"
    (trial,) = doc["trials"]
    assert trial["status"] == "TERMINATED" and crash.read_text().strip() == trial["trial_id"]
    assert trial["seed"] == 3 and trial["metrics"]["steps"] >= 1024
    spec = ExperimentSpec.from_json(doc["spec"])
    ref = run_deep(spec, {}, [3], tmp_path / "uninterrupted")
    assert per_seed(ref)[0]["metrics"] == trial["metrics"]
    assert per_seed(ref)[0]["curve"] == trial["curve"] and len(trial["curve"]["x"]) == 2
    agents = [
        load(out / "trials" / trial["trial_id"] / "seed-3"),
        load(tmp_path / "uninterrupted" / "seed-3"),
    ]
    for p, q in zip(*(ag.state_parameters() for ag in agents), strict=True):
        assert np.array_equal(p.numpy(), q.numpy())


def test_a_killed_driver_is_resumed_and_runs_every_trial_once(tmp_path):
    """Killed once a trial has finished, resumed: no kept result is computed again.

    Two trials run at a time (this module's Ray has 2 CPUs), so the second of a pair can
    be finishing when the driver is killed: its result kept, its line in the trace not yet
    written. What the test holds to is therefore read off the folder once the kill has
    taken effect: a trial whose result was kept by then is never computed after it, and
    every other trial is computed after it exactly once.
    """
    out = tmp_path / "killed"
    trace = tmp_path / "trace.txt"
    alphas = ["0.1", "0.2", "0.3", "0.4"]
    env = {
        **os.environ,
        "POLICYLAB_SWEEP_TRACE": str(trace),
        "POLICYLAB_SWEEP_TRIAL_DELAY": "1.5",  # a trial waits before it computes
        "RAY_USAGE_STATS_ENABLED": "0",
    }
    address = ray.get_runtime_context().gcs_address  # the driver joins this module's Ray
    cmd = [
        sys.executable, "-m", "policylab", "sweep", "q-learning", "CliffWalking-v1",
        "--seeds", "2", "--episodes", "100", "--set", "alpha=" + ",".join(alphas),
        "--address", address, "--out", str(out), "--json",
    ]  # fmt: skip
    proc = subprocess.Popen(
        cmd, env=env, cwd=REPO, start_new_session=True,
        stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
    )  # fmt: skip
    try:
        deadline = time.monotonic() + 120
        while time.monotonic() < deadline and proc.poll() is None:
            if trace.is_file() and trace.read_text().split():
                break
            time.sleep(0.2)
        assert proc.poll() is None, "the sweep ended before it could be killed"
        assert trace.is_file(), "no trial finished within 120 s"
        time.sleep(0.5)  # the next trials are in their delay: the kill lands between trials
    finally:
        os.killpg(proc.pid, signal.SIGKILL)  # the driver dies; Ray ends its trials
        proc.wait()
    time.sleep(2.0)  # Ray stops the dead driver's trials
    done_before = trace.read_text().split()
    kept_before = {p.parent.name for p in (out / "trials").glob("*/result.json")}
    assert set(done_before) <= kept_before
    assert len(kept_before) < len(alphas)
    doc = resume(out)
    trials = doc["trials"]
    assert sorted((t["config"]["alpha"], t["seed"]) for t in trials) == sorted(
        (float(a), s) for a in alphas for s in (0, 1)
    )
    assert {t["status"] for t in trials} == {"TERMINATED"}
    computed = trace.read_text().split()
    assert sorted(computed) == sorted(set(computed)), "a trial was computed twice"
    done_after = computed[len(done_before) :]
    assert not kept_before & set(done_after), "a kept result was computed again"
    ids = {t["tune_trial_id"] for t in trials}  # one Tune trial per alpha, both seeds in it
    assert len(ids) == len(alphas) and kept_before | set(done_after) == ids

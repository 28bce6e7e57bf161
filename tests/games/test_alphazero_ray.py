"""AlphaZero's self-play on Ray: the same games as in this process and in worker processes.

One run on a local Ray (started by the run itself, 2 workers) is shared by the module:
SIGTERM stops it in its second iteration. Oracles: the checkpoint of its first
iteration equals, array for array, those of the same settings played in this process
and in one worker process (the replay of self-play games and the trained weights).
"""

from __future__ import annotations

import os
import signal
import time

import numpy as np
import pytest
from tests.games.test_alphazero import TINY as SMOKE

from policylab.exceptions import InvalidArgumentError, TrainingInterrupted
from policylab.games.alphazero import _RayWorkers, default_config, train_alphazero

pytest.importorskip("torch")
ray = pytest.importorskip("ray")

# the smoke run's settings, with 6 games in batches of 2: three batches, dealt 2 + 1 to
# two workers
TINY = {**SMOKE, "iterations": 1, "games_per_iteration": 6, "parallel_games": 2}


def _tensors(run):
    from policylab.deep.common.checkpoint import load_checkpoint, to_numpy_tree

    meta, tensors = load_checkpoint(run / "checkpoint.pt")
    return meta, {k: to_numpy_tree(tensors[k]) for k in ("replay", "net", "best")}


@pytest.fixture(scope="module")
def ray_run(tmp_path_factory):
    """A 2-iteration run on its own local Ray, SIGTERM'd during the second iteration."""
    assert not ray.is_initialized()
    before = signal.getsignal(signal.SIGTERM)
    run = tmp_path_factory.mktemp("az") / "ray"
    cpus = []
    plays = []
    play = _RayWorkers.play

    def on_iteration(done, total, metrics):
        cpus.append(ray.cluster_resources().get("CPU"))

    def play_and_signal(self, args, chunks, poll):
        """The second iteration's play: SIGTERM while its tasks run (not on a timer)."""
        plays.append(len(plays) + 1)

        def poll_and_signal():
            if len(plays) == 2:
                os.kill(os.getpid(), signal.SIGTERM)  # the run sees it in this poll
            poll()

        return play(self, args, chunks, poll_and_signal)

    cfg = default_config("tic-tac-toe", **{**TINY, "iterations": 2, "workers": 2})
    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(_RayWorkers, "play", play_and_signal)
        with pytest.raises(TrainingInterrupted) as stop:
            train_alphazero("tic-tac-toe", run, cfg, backend="ray", on_iteration=on_iteration)
    assert plays == [1, 2]  # stopped in the second iteration's play
    return {
        "run": run,
        "stop": stop.value,
        "cpus": cpus,
        "ray_after": ray.is_initialized(),
        "sigterm_after": signal.getsignal(signal.SIGTERM),
        "sigterm_before": before,
    }


def test_ray_plays_the_same_games_as_this_process_and_worker_processes(ray_run, tmp_path):
    meta, on_ray = _tensors(ray_run["run"])
    assert meta["iteration"] == 1 and meta["config"]["backend"] == "ray"
    for where in ({"workers": 0}, {"workers": 1, "backend": "processes"}):
        run = tmp_path / str(where["workers"])
        train_alphazero("tic-tac-toe", run, default_config("tic-tac-toe", **{**TINY, **where}))
        _, other = _tensors(run)
        assert len(other["replay"]["lengths"]) == 6
        for part in ("replay", "net", "best"):
            assert other[part].keys() == on_ray[part].keys()
            for k in other[part]:
                assert np.array_equal(other[part][k], on_ray[part][k]), (where, part, k)


def test_local_ray_has_the_workers_cpus_and_stops_with_the_run(ray_run):
    assert ray_run["cpus"] == [2.0]  # num_cpus = workers
    assert ray_run["ray_after"] is False  # shut down when the run stopped
    assert ray_run["sigterm_after"] == ray_run["sigterm_before"]  # ray.init's handler undone


def test_sigterm_keeps_the_checkpoint_of_the_last_whole_iteration(ray_run):
    import json

    stop = ray_run["stop"]
    assert (stop.step, stop.signal) == (1, signal.SIGTERM)
    assert json.loads((ray_run["run"] / "run.json").read_text())["iteration"] == 1
    rows = (ray_run["run"] / "progress.csv").read_text().strip().splitlines()
    assert len(rows) == 1 + 1  # the log matches the checkpoint
    # the run continues where it stopped, here in this process
    train_alphazero("tic-tac-toe", ray_run["run"], resume=True, workers=0, backend="processes")
    assert json.loads((ray_run["run"] / "run.json").read_text())["iteration"] == 2


def test_an_unreachable_address_is_refused_within_seconds(tmp_path):
    cfg = default_config("tic-tac-toe", **{**TINY, "workers": 2, "backend": "ray"})
    t0 = time.monotonic()
    with pytest.raises(InvalidArgumentError, match="cannot reach a Ray cluster at '127.0.0.1:9'"):
        train_alphazero("tic-tac-toe", tmp_path / "x", cfg, ray_address="127.0.0.1:9")
    assert time.monotonic() - t0 < 10  # not a hang; the probe waits 3 s at most
    assert not (tmp_path / "x").exists()  # refused before the run folder is touched
    assert not ray.is_initialized()


@pytest.mark.parametrize(
    ("settings", "message"),
    [
        ({"backend": "dask"}, "backend must be one of processes, ray; got 'dask'"),
        ({"backend": "ray", "workers": 0}, "workers must be >= 1"),
        ({"ray_address": "head:6379"}, "needs backend=ray"),
        ({"backend": "ray", "ray_address": "head:99999"}, "ray_address must be HOST:PORT"),
    ],
)
def test_bad_backend_settings(settings, message):
    with pytest.raises(InvalidArgumentError, match=message):
        default_config("tic-tac-toe", **settings)


def test_cli_refuses_an_unreachable_address_with_one_line(capsys, tmp_path):
    from policylab.cli.main import main

    argv = ["train", "alphazero", "tic-tac-toe", "--out", str(tmp_path / "r")]
    argv += ["--set", "backend=ray", "--set", "ray_address=127.0.0.1:9", "--no-progress"]
    with pytest.raises(SystemExit) as exc:
        main(argv)
    err = capsys.readouterr().err
    assert exc.value.code == 2 and len(err.strip().splitlines()) == 1
    assert "cannot reach a Ray cluster" in err and "ray_address" in err
    assert not (tmp_path / "r").exists()

"""Checkpoints: round trip, refusal of unsafe pickles, atomic writes, resume."""

from __future__ import annotations

import os
import pickle
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import torch

import policylab as pl
from policylab.deep.common.checkpoint import atomic_write_bytes, load_checkpoint, save_checkpoint
from policylab.exceptions import CheckpointError

OBS = np.random.default_rng(0).normal(scale=0.5, size=(64, 4)).astype(np.float32)


@pytest.mark.parametrize("algo", ["ppo", "dqn"])
def test_save_load_gives_identical_actions(tmp_path: Path, algo: str) -> None:
    cls = pl.deep.ALGORITHMS[algo]
    agent = (
        cls("CartPole-v1", seed=3, learning_starts=100)
        if algo == "dqn"
        else cls("CartPole-v1", seed=3, n_steps=64)
    )
    agent.learn(400)
    agent.save(tmp_path / "a.pt")
    loaded = cls.load(tmp_path / "a.pt")
    np.testing.assert_array_equal(agent.predict(OBS), loaded.predict(OBS))
    assert loaded.num_timesteps == agent.num_timesteps
    assert loaded.config == agent.config
    assert pl.deep.load(tmp_path / "a.pt").algo == algo
    for p, q in zip(agent.state_parameters(), loaded.state_parameters(), strict=True):
        torch.testing.assert_close(p, q)


def test_gaussian_policy_round_trip_with_normalizer(tmp_path: Path) -> None:
    agent = pl.deep.PPO("Pendulum-v1", n_steps=32, normalize_obs=True, seed=1)
    agent.learn(64)
    agent.save(tmp_path / "p.pt")
    loaded = pl.deep.PPO.load(tmp_path / "p.pt")
    obs = np.random.default_rng(1).normal(size=(5, 3)).astype(np.float32)
    np.testing.assert_array_equal(agent.predict(obs), loaded.predict(obs))
    np.testing.assert_allclose(loaded.obs_normalizer.rms.mean, agent.obs_normalizer.rms.mean)


class _Exploit:
    """Unpickling this object runs code: it creates a marker file."""

    def __init__(self, marker: str) -> None:
        self.marker = marker

    def __reduce__(self) -> tuple[object, tuple[str]]:
        return (os.system, (f"touch {self.marker}",))


@pytest.mark.filterwarnings("ignore:Detected pickle protocol")
def test_checkpoint_that_runs_code_on_load_is_refused(tmp_path: Path) -> None:
    marker = tmp_path / "pwned"
    # a torch-format file whose payload unpickles to os.system(...)
    evil = tmp_path / "evil.pt"
    torch.save(
        {
            "format": "policylab-checkpoint",
            "version": 1,
            "meta": "{}",
            "tensors": {"x": _Exploit(str(marker))},
        },
        evil,
    )
    with pytest.raises(CheckpointError, match="refusing"):
        load_checkpoint(evil)
    with pytest.raises(CheckpointError, match="refusing"):
        pl.deep.PPO.load(evil)
    # a plain pickle file, not even a torch archive
    raw = tmp_path / "raw.pt"
    raw.write_bytes(pickle.dumps(_Exploit(str(marker))))
    with pytest.raises(CheckpointError):
        pl.deep.DQN.load(raw)
    assert not marker.exists()


def test_malformed_or_foreign_checkpoints_are_refused(tmp_path: Path) -> None:
    with pytest.raises(CheckpointError, match="no checkpoint"):
        load_checkpoint(tmp_path / "missing.pt")
    junk = tmp_path / "junk.pt"
    junk.write_bytes(b"not a checkpoint")
    with pytest.raises(CheckpointError):
        load_checkpoint(junk)
    plain = tmp_path / "plain.pt"
    torch.save({"w": torch.zeros(2)}, plain)
    with pytest.raises(CheckpointError, match="not a policylab checkpoint"):
        load_checkpoint(plain)
    agent = pl.deep.PPO("CartPole-v1", n_steps=16)
    agent.save(tmp_path / "ppo.pt")
    with pytest.raises(CheckpointError, match="'ppo' agent, not 'dqn'"):
        pl.deep.DQN.load(tmp_path / "ppo.pt")


def test_save_is_atomic_when_interrupted(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    path = tmp_path / "ckpt.pt"
    save_checkpoint(path, {"n": 1}, {"w": np.ones(3)})

    def crash(*args: object) -> None:
        raise KeyboardInterrupt  # interrupted between writing the new file and renaming it

    monkeypatch.setattr(os, "replace", crash)
    with pytest.raises(KeyboardInterrupt):
        save_checkpoint(path, {"n": 2}, {"w": np.zeros(3)})
    monkeypatch.undo()
    meta, tensors = load_checkpoint(path)
    assert meta == {"n": 1}
    np.testing.assert_array_equal(tensors["w"].numpy(), np.ones(3))
    assert [p.name for p in tmp_path.iterdir()] == ["ckpt.pt"]  # no temporary file left behind


def test_process_killed_mid_save_leaves_previous_checkpoint(tmp_path: Path) -> None:
    path = tmp_path / "ckpt.pt"
    save_checkpoint(path, {"n": 1}, {"w": np.ones(3)})
    # a child process dies (os._exit, no cleanup) after writing half of the new data
    code = f"""
import os
import policylab.deep.common.checkpoint as c
real_fdopen = os.fdopen
class Half:
    def __init__(self, f): self.f = f
    def __enter__(self): return self
    def __exit__(self, *a): pass
    def write(self, data): self.f.write(data[: len(data) // 2]); self.f.flush(); os._exit(9)
os.fdopen = lambda fd, mode: Half(real_fdopen(fd, mode))
c.save_checkpoint({str(path)!r}, {{"n": 2}}, {{"w": __import__("numpy").zeros(3)}})
"""
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, check=False)
    assert proc.returncode == 9, proc.stderr.decode()
    meta, _ = load_checkpoint(path)
    assert meta == {"n": 1}


def test_atomic_write_replaces_whole_file(tmp_path: Path) -> None:
    p = tmp_path / "x.bin"
    atomic_write_bytes(p, b"a" * 10)
    atomic_write_bytes(p, b"b")
    assert p.read_bytes() == b"b"


def test_resume_continues_the_run(tmp_path: Path) -> None:
    run = tmp_path / "run"
    agent = pl.deep.DQN(
        "CartPole-v1", seed=0, learning_starts=200, checkpoint_every=500, buffer_size=5000
    )
    agent.learn(1000, run_dir=run)
    assert (
        (run / "checkpoint.pt").is_file()
        and (run / "progress.csv").is_file()
        and (run / "run.json").is_file()
    )
    assert any((run / "tb").iterdir())
    resumed = pl.deep.DQN.resume(run)
    assert resumed.num_timesteps == agent.num_timesteps and resumed.target_steps == 1000
    assert len(resumed.replay) == len(agent.replay)
    np.testing.assert_array_equal(
        resumed.replay.obs[: len(agent.replay)], agent.replay.obs[: len(agent.replay)]
    )
    assert resumed.rng.bit_generator.state == agent.rng.bit_generator.state
    np.testing.assert_array_equal(resumed.predict(OBS), agent.predict(OBS))
    resumed.learn(1500, run_dir=run)
    assert resumed.num_timesteps >= 1500
    rows = (run / "progress.csv").read_text().strip().splitlines()
    assert rows[0].startswith("step,") and int(rows[-1].split(",")[0]) >= 1500

"""The quick tour writes every figure under --out and lists it."""

from __future__ import annotations

import pytest

from policylab.cli.main import main

PNG = b"\x89PNG\r\n\x1a\n"


def test_quick_tour_runs_and_writes_its_figures(capsys, tmp_path):
    """``policylab tour --quick``: the notes' numbers, then every figure, each listed."""
    out = tmp_path / "tour"
    with pytest.raises(SystemExit) as e:
        main(["tour", "--quick", "--out", str(out)])
        raise SystemExit(0)
    assert int(e.value.code or 0) == 0
    text = capsys.readouterr().out
    assert "-6" in text and "-5" in text and "Tour complete" in text
    printed = "".join(text.split())  # rich may wrap long paths
    written = sorted(out.glob("*.png"))
    names = {p.name for p in written}
    assert {
        "01_interaction_loop.png",
        "02_slippery_episode.png",
        "06_mountain_bad_policy.png",
        "07_mountain_optimal.png",
        "05_robot_optimal.png",
        "08_slippery_q_table.png",
        "12_frozenlake_learning.png",
        "14_gridworld-5x5.png",
        "14_gamblers-problem.png",
    } <= names
    assert len(written) >= 13
    for p in written:
        assert p.read_bytes()[:8] == PNG and p.stat().st_size > 5000
        assert p.name in printed  # the tour lists the paths

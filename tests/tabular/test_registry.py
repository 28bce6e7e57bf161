"""One registry entry per algorithm: the public function, the registry and the CLI agree.

Also the package guide's "how to add a learner": a toy learner registered as the guide
says appears in ``policylab learn --help`` and runs from the command line.
"""

from __future__ import annotations

import inspect
import json
import subprocess
import sys
import textwrap

import pytest

import policylab
from policylab import tabular as tab
from policylab.tabular import _generate
from policylab.tabular.td import TD_ENTRIES


def test_the_generated_learners_are_current():
    """td.py's learners are exactly what the generator writes from TD_ENTRIES."""
    path = _generate.target()
    assert _generate.updated(path.read_text()) == path.read_text(), (
        "run python -m policylab.tabular._generate"
    )


@pytest.mark.parametrize("entry", TD_ENTRIES, ids=lambda e: e.name)
def test_each_td_learner_is_its_entry(entry):
    fn = getattr(tab, entry.function)
    spec = tab.algorithm(entry.name)
    assert spec.learner is fn and spec.description == entry.description
    params = inspect.signature(fn).parameters
    doc = inspect.getdoc(fn) or ""
    assert doc.startswith(entry.title) and entry.equation.splitlines()[0] in doc
    for opt in spec.options:  # every CLI option sets a documented parameter, default as said
        assert opt.param in params, (entry.name, opt.param)
        assert f"{opt.param}: " in doc
        assert repr(params[opt.param].default) == repr(eval(opt.value)), opt.param
    assert params["episodes"].default == spec.default_episodes
    assert ("policy" in params) == (spec.kind == "prediction")
    # the docstring is in the source, not added at import time
    assert entry.title in inspect.getsource(fn)


def test_registry_specs_keep_the_fields_other_commands_read():
    for spec in tab.list_algorithms():
        assert spec.name and callable(spec.learner) and spec.description
        assert spec.kind in ("prediction", "control") and spec.default_episodes > 0
        for opt in spec.options:
            assert opt.flag.startswith("--") and opt.param and opt.kind and opt.help
            assert hasattr(opt, "default")


TOY = textwrap.dedent(
    '''
    from policylab import tabular
    from policylab.tabular import Option, register_algorithm


    def every_visit_td0(problem, policy=None, *, episodes=100, seed=None, alpha=None, **kw):
        """TD(0) with the 1/n step size by default: a toy learner added as the guide says."""
        return tabular.td0(problem, policy, episodes=episodes, seed=seed,
                           alpha="1/n" if alpha is None else alpha, **kw)


    register_algorithm(
        "toy-td0",
        every_visit_td0,
        "Toy: TD(0) with the sample-average step size 1/n.",
        options=(Option("--alpha", "alpha", "schedule", "Step size (default 1/n)."),),
        kind="prediction",
        default_episodes=50,
    )
    '''
)


def _cli(tmp_path, *argv: str) -> subprocess.CompletedProcess[str]:
    (tmp_path / "toy_learner.py").write_text(TOY)
    code = f"import toy_learner\nfrom policylab.cli.main import main\nmain({list(argv)!r})\n"
    return subprocess.run(
        [sys.executable, "-c", code],
        cwd=tmp_path,
        capture_output=True,
        text=True,
        env={"PYTHONPATH": str(tmp_path), "COLUMNS": "200", "PATH": "/usr/bin:/bin"},
        check=False,
    )


def test_a_toy_learner_added_as_the_guide_says_is_in_learn_help_and_runs(tmp_path):
    assert "toy-td0" in (policylab.tabular.__doc__ or "") or "register_algorithm" in (
        policylab.tabular.__doc__ or ""
    )
    done = _cli(tmp_path, "learn", "--help")
    assert done.returncode == 0, done.stderr
    assert "toy-td0" in done.stdout and "sample-average step size" in done.stdout
    done = _cli(
        tmp_path, "learn", "toy-td0", "random-walk", "--episodes", "20", "--seed", "3", "--json"
    )
    assert done.returncode == 0, done.stderr
    got = json.loads(done.stdout)
    want = tab.td0(policylab.problems.random_walk(), episodes=20, seed=3, alpha="1/n")
    assert got["v"] == [float(x) for x in want.v]
    # seed_study takes it too (one run at a time: it is not a built-in compiled loop)
    namespace: dict[str, object] = {}
    exec(TOY, namespace)
    try:
        study = tab.seed_study("toy-td0", policylab.problems.random_walk(), [3], episodes=20)
        assert list(study.v[0]) == list(want.v)
    finally:
        from policylab.tabular import registry

        registry._ALGORITHMS.pop("toy-td0", None)

import numpy as np
import pytest

from policylab.exceptions import InvalidArgumentError
from policylab.validation import (
    check_count,
    check_gamma,
    check_number,
    check_output_dir,
    check_output_file,
    check_seed,
    fmt_number,
    normalize_name,
)


def test_fmt_number_shows_enough_digits_and_no_numpy_repr():
    assert fmt_number(np.float64(-0.5)) == "-0.5"
    assert fmt_number(np.float32(1) + np.float32(3e-8)) in {"1.0", "1.0000000298023224"}
    assert fmt_number(1 + 3e-8) == "1.00000003"
    assert fmt_number(np.int64(7)) == "7"


def test_normalize_name():
    assert normalize_name(" Q_Learning ") == "q-learning"


@pytest.mark.parametrize(
    ("call", "words"),
    [
        (lambda: check_seed(-1), "seed must be a non-negative integer"),
        (lambda: check_seed(1.5), "seed must be an integer"),
        (lambda: check_seed(True), "seed must be an integer"),
        (lambda: check_count(0, "--episodes"), "--episodes must be a positive integer; got 0"),
        (lambda: check_gamma(1.5), "gamma must be in [0, 1]; got 1.5"),
        (lambda: check_gamma("x"), "gamma must be a number"),
        (lambda: check_number(float("nan"), "alpha"), "alpha must be a finite number; got nan"),
        (lambda: check_number(0, "tol", low=0, low_open=True), "tol must be > 0"),
    ],
)
def test_bad_values_name_argument_and_value(call, words):
    with pytest.raises(InvalidArgumentError) as err:
        call()
    assert words in str(err.value)


def test_good_values_come_back_canonical():
    assert check_seed(None) is None
    assert check_seed(np.int64(3)) == 3
    assert check_gamma(None, 0.9) == 0.9
    assert check_count(np.int32(5), "n") == 5


def test_output_paths_checked_before_work(tmp_path):
    with pytest.raises(InvalidArgumentError, match="suffix"):
        check_output_file(tmp_path / "a.xyz", "--plot", [".png", ".svg"])
    with pytest.raises(InvalidArgumentError, match="is a folder"):
        check_output_file(tmp_path, "--plot")
    with pytest.raises(InvalidArgumentError, match="cannot be written"):
        check_output_file("/proc/nope/x.png", "--plot", [".png"])
    (tmp_path / "f").write_text("x")
    with pytest.raises(InvalidArgumentError, match="existing file"):
        check_output_dir(tmp_path / "f", "--out")
    with pytest.raises(InvalidArgumentError, match="cannot be written"):
        check_output_dir("/proc/nope", "--out")
    assert check_output_dir(tmp_path / "new" / "sub", "--out") == tmp_path / "new" / "sub"
    assert not (tmp_path / "new").exists()


def test_fmt_number_near_a_target_keeps_the_digits_that_matter():
    assert fmt_number(0.9299999999999999, near=1.0) == "0.93"
    assert fmt_number(1 + 3e-8, near=1.0) == "1.00000003"
    assert fmt_number(np.float64(2.0), near=1.0) == "2.0" or fmt_number(2.0, near=1.0) == "2"


def test_check_count_states_a_power_of_two_bound_readably():
    with pytest.raises(InvalidArgumentError, match=r"in \[1, 2\*\*62\]; got 100000000000000000000"):
        check_count(10**20, "--episodes", maximum=2**62)


def test_as_generator_and_check_choice():
    from policylab.validation import as_generator, check_choice

    g = np.random.default_rng(0)
    assert as_generator(g) is g
    assert as_generator(3).integers(100) == np.random.default_rng(3).integers(100)
    with pytest.raises(InvalidArgumentError, match="seed must be a non-negative integer"):
        as_generator(-1)
    with pytest.raises(InvalidArgumentError, match="seed must be an integer"):
        as_generator("0")
    assert check_choice(" VI", ["vi", "pi"], "--method") == "vi"
    with pytest.raises(InvalidArgumentError, match=r"did you mean 'pi'\?"):
        check_choice("pii", ["vi", "pi", "lp"], "--method")


def test_check_figure_path(tmp_path):
    from policylab.validation import check_figure_path

    assert check_figure_path(tmp_path / "a") == tmp_path / "a.png"
    assert check_figure_path(tmp_path / "sub" / "b.SVG") == tmp_path / "sub" / "b.SVG"
    with pytest.raises(InvalidArgumentError, match="'.xyz'; expected one of .png, .svg, .pdf"):
        check_figure_path(tmp_path / "a.xyz")
    with pytest.raises(InvalidArgumentError, match="is a folder"):
        check_figure_path(tmp_path)
    with pytest.raises(InvalidArgumentError, match="cannot be written"):
        check_figure_path("/proc/nope/x.png", "--plot")


def test_one_gamma_check_for_every_entry_point():
    # planning, tabular and the MDP itself give the same words for the same bad gamma
    import policylab as pl
    from policylab.planning._checks import check_gamma as planning_gamma
    from policylab.tabular.common import check_gamma as tabular_gamma

    mdp = pl.problems.recycling_robot()
    msgs = set()
    for call in (
        lambda: planning_gamma(mdp, 1.5),
        lambda: tabular_gamma(1.5, 0.9),
        lambda: mdp.with_gamma(1.5),
        lambda: check_gamma(1.5),
    ):
        with pytest.raises(InvalidArgumentError) as err:
            call()
        msgs.add(str(err.value))
    assert msgs == {"gamma must be in [0, 1]; got 1.5"}
    assert planning_gamma(mdp, None) == mdp.gamma


@pytest.mark.parametrize(
    ("text", "words"),
    [
        ("exp:1,2", "decay (the second number) must lie in (0, 1]"),
        ("linear:1,0.1,0", "steps (the third number"),
        ("inverse:1,-1,0", "power must be > 0"),
        ("inverse:-1", "scale must be >= 0"),
        ("exp:1", "has 1 number; exp takes 2 to 3"),
        ("linear:1,x,3", "number 2 ('x') is not a number"),
        ("cosine:1,2", "cannot read schedule 'cosine:1,2'"),
        ("nan", "must be finite; got nan"),
    ],
)
def test_schedule_strings_say_which_number_is_wrong(text, words):
    from policylab.tabular.schedules import Schedule

    with pytest.raises(InvalidArgumentError) as err:
        Schedule.parse(text)
    assert words in str(err.value) and f"{text!r}" in str(err.value)


def test_tabular_learners_check_their_seed():
    import policylab as pl
    from policylab import tabular

    mdp = pl.problems.recycling_robot()
    with pytest.raises(InvalidArgumentError, match="seed must be a non-negative integer"):
        tabular.q_learning(mdp, episodes=5, seed=-1)
    with pytest.raises(InvalidArgumentError, match="seed must be an integer"):
        tabular.mc_control(pl.problems.gridworld_4x4(), episodes=5, seed=0.5)
    with pytest.raises(InvalidArgumentError, match="unknown TD algorithm 'q-lerning'"):
        tabular.seed_study("q-lerning", mdp, seeds=2, episodes=5)

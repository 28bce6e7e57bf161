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

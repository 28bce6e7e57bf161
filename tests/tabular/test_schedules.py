import numpy as np
import pytest

from policylab.exceptions import InvalidArgumentError
from policylab.tabular import Schedule, schedule_value


def test_values_match_formulas():
    assert Schedule.constant(0.1)(7) == 0.1
    assert Schedule.inverse()(4) == 0.25
    assert Schedule.inverse(2.0, 0.5, 0.3)(100) == pytest.approx(0.3)
    assert Schedule.inverse(2.0, 0.5)(16) == pytest.approx(0.5)
    assert Schedule.exponential(1.0, 0.5, 0.1)(3) == 0.25
    assert Schedule.exponential(1.0, 0.5, 0.1)(10) == 0.1
    lin = Schedule.linear(1.0, 0.1, 9)
    assert lin(1) == 1.0 and lin(10) == pytest.approx(0.1) and lin(1000) == pytest.approx(0.1)
    assert lin(5.5) == pytest.approx(0.55)


def test_parse_round_trip_and_kernel_function():
    for text in ("0.1", "1/n", "exp:1,0.99,0.05", "linear:1,0.05,1000", "inverse:2,0.6,0.01"):
        s = Schedule.parse(text)
        assert Schedule.parse(str(s)) == s
        assert schedule_value(s.params, 17.0) == s(17)
    np.testing.assert_allclose(Schedule.inverse().values(4), [1, 1 / 2, 1 / 3, 1 / 4])


@pytest.mark.parametrize("bad", ["", "abc", "exp:1", "linear:1,2", "exp:1,1.5"])
def test_parse_errors_are_clear(bad):
    with pytest.raises(InvalidArgumentError, match=r"schedule|decay"):
        Schedule.parse(bad)


def test_range_check():
    with pytest.raises(InvalidArgumentError, match="epsilon"):
        Schedule.constant(1.5).check_range(0, 1, "epsilon")

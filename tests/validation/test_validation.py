import numpy as np
import pytest
import torch

from tactile_torch.validation import (
    check_finite,
    check_floating,
    check_positive,
    check_shape,
    check_tensor,
    numpy_rng,
    torch_generator,
)


def test_check_shape_binds_named_sizes():
    sizes = check_shape(torch.zeros(2, 5, 3, 4, 6), "frames", ["B", "T", 3, "H", "W"])
    assert sizes == {"B": 2, "T": 5, "H": 4, "W": 6}


def test_check_shape_leading_star():
    assert check_shape(torch.zeros(7, 2, 3, 10), "windows", ["*", 3, "W"]) == {"W": 10}
    with pytest.raises(ValueError, match=r"windows must have shape \(\*, 3, W\), got \(4,\)"):
        check_shape(torch.zeros(4), "windows", ["*", 3, "W"])


@pytest.mark.parametrize(
    "shape", [(2, 100, 64, 64), (2, 100, 4, 8, 8), (1, 2, 3, 4, 5, 6)], ids=["rank4", "channels", "rank6"]
)
def test_check_shape_message_names_argument_expected_and_given(shape):
    with pytest.raises(ValueError) as err:
        check_shape(torch.zeros(shape), "frames", ["B", "T", 3, "H", "W"])
    assert str(err.value) == f"frames must have shape (B, T, 3, H, W), got {shape}"


def test_check_shape_repeated_name_must_agree():
    check_shape(torch.zeros(3, 3), "K", ["N", "N"])
    with pytest.raises(ValueError, match="equal N"):
        check_shape(torch.zeros(3, 4), "K", ["N", "N"])


def test_type_dtype_finite_checks():
    with pytest.raises(TypeError, match=r"x must be a torch\.Tensor, got ndarray"):
        check_tensor(np.zeros(3), "x")
    with pytest.raises(TypeError, match=r"floating dtype.*torch\.int64"):
        check_floating(torch.zeros(3, dtype=torch.int64), "x")
    x = torch.zeros(2, 3)
    x[1, 2] = float("nan")
    with pytest.raises(
        ValueError, match=r"x must be finite, got 1 NaN/inf value\(s\) \(first at index \(1, 2\)\)"
    ):
        check_finite(x, "x")
    check_finite(torch.zeros(3), "x")


@pytest.mark.parametrize(
    ("value", "err"),
    [(0, ValueError), (-1.0, ValueError), ("1", TypeError), (True, TypeError), (float("inf"), ValueError)],
)
def test_check_positive_rejects(value, err):
    with pytest.raises(err, match="C must"):
        check_positive(value, "C")


def test_random_state_conversions_are_reproducible():
    a = numpy_rng(3).normal(size=4)
    b = numpy_rng(3).normal(size=4)
    np.testing.assert_array_equal(a, b)
    g1 = torch_generator(5)
    g2 = torch_generator(np.random.default_rng(5))
    # An int seed and a numpy generator seeded alike give the same torch stream.
    assert torch.equal(torch.rand(3, generator=g1), torch.rand(3, generator=g2))
    tg = torch.Generator().manual_seed(1)
    assert torch_generator(tg) is tg
    x = numpy_rng(torch.Generator().manual_seed(9)).random()
    y = numpy_rng(torch.Generator().manual_seed(9)).random()
    assert x == y
    # scikit-learn's legacy generator (its "random_state" constraint allows it): one draw seeds ours.
    legacy = [numpy_rng(np.random.RandomState(4)).random() for _ in range(2)]
    assert legacy[0] == legacy[1] != numpy_rng(np.random.RandomState(5)).random()
    with pytest.raises(TypeError, match="random_state must be"):
        numpy_rng("seed")

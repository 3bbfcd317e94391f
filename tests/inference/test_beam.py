"""The beam step's kernel: how it compares weights, breaks ties and checks its arguments."""

import numpy as np
import pytest

from globe.inference import _beam
from globe.inference.beam import tie_key


def _rounded(weights):
    """The definition: the mantissa rounded to 30 bits, half to even."""
    mantissa, exponent = np.frexp(weights)
    return np.ldexp(np.round(mantissa * (1 << 30)), exponent - 30)


def test_tie_key_rounds_the_mantissa_to_30_bits_half_to_even():
    rng = np.random.default_rng(0)
    bits = rng.integers(1 << 52, 0x7FE << 52, 20_000, dtype=np.int64)
    halves = bits & ~np.int64((1 << 23) - 1) | (1 << 22)  # exactly half way: even wins
    weights = np.concatenate([rng.random(20_000), bits.view(np.float64), halves.view(np.float64),
                              [0.0, 5e-324, 1e-310, 1.0, np.nextafter(1.0, 2.0), np.finfo(float).tiny]])
    assert np.array_equal(tie_key(weights), _rounded(weights))
    assert tie_key(np.array([0.1 + 0.2]))[0] == tie_key(np.array([0.3]))[0]


def _select(weight, lex, names, act, keep=1):
    n = len(weight)
    z = np.zeros(n, dtype=np.int64)
    kept, w, _ = _beam.select(True, keep, 0.0, 1, z, np.arange(n, dtype=np.int64), np.asarray(act, dtype=np.int64),
                              np.asarray(weight, dtype=np.float64), np.arange(n, dtype=np.int64),
                              np.asarray(lex, dtype=np.int64), np.asarray(names, dtype=np.int64))
    return np.frombuffer(kept, dtype=np.int64).tolist(), np.frombuffer(w, dtype=np.float64).tolist()


def test_weights_equal_but_for_their_last_bits_tie_and_the_history_first_in_name_order_wins():
    third = 1 / 3
    assert _select([third, np.nextafter(third, 1.0)], lex=[1, 0], names=[0, 1], act=[0, 0])[0] == [1]
    assert _select([third, third], lex=[0, 0], names=[1, 0], act=[0, 1])[0] == [1]  # same parent: by name
    assert _select([0.3, 0.4], lex=[0, 1], names=[0, 1], act=[0, 1])[0] == [1]  # else the most probable


def test_merged_states_sum_and_the_kept_are_renormalised():
    z = np.zeros(3, dtype=np.int64)
    kept, w, _ = _beam.select(True, 5, 0.0, 1, z, np.arange(3, dtype=np.int64), z, np.array([0.2, 0.3, 0.1]),
                              np.array([7, 7, 8], dtype=np.int64), np.arange(3, dtype=np.int64), z[:1])
    assert np.frombuffer(kept, dtype=np.int64).tolist() == [1, 2]  # the group's most probable represents it
    assert np.frombuffer(w, dtype=np.float64) == pytest.approx([5 / 6, 1 / 6])


def test_an_index_out_of_range_is_an_error_not_a_read():
    z = np.zeros(1, dtype=np.int64)
    with pytest.raises(ValueError, match="out of range"):
        _beam.select(True, 1, 0.0, 1, z, np.array([3], dtype=np.int64), z, np.ones(1), z, z, z)
    with pytest.raises(ValueError, match="float64"):
        _beam.select(True, 1, 0.0, 1, z, z, z, np.ones(1, dtype=np.float32), z, z, z)


def test_histories_out_of_query_order_are_an_error():
    rows, w = np.full((2, 1), 1.0), np.ones(2)
    none, back = np.zeros(0), np.array([1, 0], dtype=np.int64)
    with pytest.raises(ValueError, match="query by query"):
        _beam.extend(0.0, 2, rows, w, back, np.full(2, -1, dtype=np.int64), none, none.astype(np.int64),
                     none.astype(np.int64))

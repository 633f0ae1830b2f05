"""m-sequences and Gold codes: period, two-valued autocorrelation, three-valued cross-correlation, spreading."""

import numpy as np
import pytest

from cbtc.errors import ConfigError
from cbtc.ranging import pn_codes


@pytest.mark.parametrize("n_bits", [5, 7, 10])
def test_m_sequence_has_full_period_and_two_valued_autocorrelation(n_bits):
    u = pn_codes.mseq(n_bits)
    n = 2 ** n_bits - 1
    assert len(u) == n
    assert int(u.sum()) == 2 ** (n_bits - 1)          # balance: one more 1 than 0
    r = np.rint(pn_codes.periodic_correlation(pn_codes.bipolar(u), pn_codes.bipolar(u))).astype(int)
    assert r[0] == n and set(r[1:].tolist()) == {-1}


def test_non_primitive_taps_are_refused():
    with pytest.raises(ConfigError):
        pn_codes.mseq(4, (4, 2))                     # x^4 + x^2 + 1 is not primitive: period 6, not 15


@pytest.mark.parametrize("n_bits", [5, 7, 10])
def test_preferred_pair_and_gold_codes_are_three_valued(n_bits):
    t = pn_codes.gold_bound(n_bits)
    allowed = {-1, -t, t - 2}                         # n = 10: {-1, -65, 63}
    u, v = pn_codes.preferred_pair(n_bits)
    r = np.rint(pn_codes.periodic_correlation(pn_codes.bipolar(u), pn_codes.bipolar(v))).astype(int)
    assert set(r.tolist()) == allowed
    a, b = pn_codes.gold_code(n_bits, 2), pn_codes.gold_code(n_bits, 9)
    r = np.rint(pn_codes.periodic_correlation(pn_codes.bipolar(a), pn_codes.bipolar(b))).astype(int)
    assert set(r.tolist()) <= allowed
    if n_bits == 10:
        assert allowed == {-1, -65, 63}


def test_spreading_round_trip_and_noise_free_despreading():
    code = pn_codes.gold_code(5, 3)
    bits = np.array([1, 0, 0, 1, 1, 0, 1, 0], dtype=np.uint8)
    chips = pn_codes.spread(bits, code)
    assert chips.shape == (8 * 31,)
    assert np.array_equal(pn_codes.despread(chips, code), bits)

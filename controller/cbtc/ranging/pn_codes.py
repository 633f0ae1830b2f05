"""Pseudo-noise codes for coded ranging and data (the CODIBDT and FOLOMIE radars): LFSR m-sequences, Gold codes,
spreading.

- `mseq(n_bits, taps)`: the maximal-length sequence (length 2^n - 1) of a Fibonacci LFSR, bits 0/1. Its periodic
  autocorrelation in +-1 form is two-valued: N at zero shift, -1 at every other shift.
- `preferred_pair(n_bits)`: two m-sequences whose periodic cross-correlation takes only the three values
  {-1, -t, t - 2} with t = 1 + 2^floor((n + 2) / 2) (for n = 10: {-1, -65, 63}). The second is the first decimated by
  q = 2^k + 1 (Gold's construction, n not divisible by 4).
- `gold_code(n_bits, index)`: member `index` of the Gold family of that pair: u, v, then u xor shift(v, k). Different
  trains use different members, so their codes stay nearly orthogonal (cross-correlation bounded by t).
- `spread(bits, code)` / `despread(chips, code)`: direct-sequence spreading of data bits by a short code (BPSK).
"""

from functools import lru_cache

import numpy as np

from cbtc.errors import ConfigError

# Fibonacci taps of primitive polynomials (output the oldest bit; feedback = xor of these delays)
PRIMITIVE_TAPS = {5: (5, 3), 7: (7, 6), 10: (10, 7)}
# decimation exponent k of the preferred pair (gcd(n, k) = 1 for n odd, 2 for n = 2 mod 4)
_GOLD_K = {5: 1, 7: 1, 10: 2}


def mseq(n_bits: int, taps=None) -> np.ndarray:
    """One period (2^n_bits - 1 chips, values 0/1, uint8) of the LFSR sequence s[k] = xor of s[k - t] for t in taps,
    started from all ones. Raises ConfigError when the taps do not give a maximal-length sequence."""
    if taps is None:
        if n_bits not in PRIMITIVE_TAPS:
            raise ConfigError(f"m-sequence: no default taps for n={n_bits}; give taps or use {sorted(PRIMITIVE_TAPS)}")
        taps = PRIMITIVE_TAPS[n_bits]
    taps = tuple(int(t) for t in taps)
    if max(taps) != n_bits or min(taps) < 1:
        raise ConfigError(f"m-sequence: taps {taps} must lie in 1..{n_bits} and include {n_bits}")
    return _mseq(n_bits, taps).copy()


@lru_cache(maxsize=32)
def _mseq(n_bits, taps):
    length = 2 ** n_bits - 1
    s = [1] * n_bits + [0] * length
    for k in range(n_bits, n_bits + length):
        bit = 0
        for t in taps:
            bit ^= s[k - t]
        s[k] = bit
    out = np.array(s[:length], dtype=np.uint8)
    register = s[length:length + n_bits]
    if register != [1] * n_bits or len(set(tuple(out[i:i + n_bits]) for i in range(length - n_bits + 1))) \
            != length - n_bits + 1:
        raise ConfigError(f"m-sequence: taps {taps} are not primitive for n={n_bits} (period is not {length})")
    return out


def bipolar(bits) -> np.ndarray:
    """0/1 bits to +1/-1 chips (0 -> +1)."""
    return 1.0 - 2.0 * np.asarray(bits, dtype=float)


def periodic_correlation(a, b) -> np.ndarray:
    """r[k] = sum_i a[i] * b[(i + k) mod N] for two equal-length sequences (floats; use bipolar chips)."""
    a = np.asarray(a, dtype=float)
    b = np.asarray(b, dtype=float)
    return np.real(np.fft.ifft(np.conj(np.fft.fft(a)) * np.fft.fft(b)))


def gold_bound(n_bits: int) -> int:
    """t(n) = 1 + 2^floor((n + 2) / 2): the largest magnitude of a preferred pair's cross-correlation."""
    return 1 + 2 ** ((n_bits + 2) // 2)


@lru_cache(maxsize=8)
def _pair(n_bits):
    if n_bits not in _GOLD_K:
        raise ConfigError(f"Gold codes: no preferred pair for n={n_bits}; use one of {sorted(_GOLD_K)}")
    u = _mseq(n_bits, PRIMITIVE_TAPS[n_bits])
    length = len(u)
    q = 2 ** _GOLD_K[n_bits] + 1
    v = u[(q * np.arange(length)) % length]
    return u, v


def preferred_pair(n_bits: int):
    """(u, v): two m-sequences of length 2^n - 1 (0/1) with three-valued cross-correlation {-1, -t, t - 2}."""
    u, v = _pair(n_bits)
    return u.copy(), v.copy()


def gold_code(n_bits: int, index: int) -> np.ndarray:
    """Member `index` (0 .. 2^n) of the Gold family: 0 -> u, 1 -> v, 2 + k -> u xor (v shifted by k)."""
    u, v = _pair(n_bits)
    length = len(u)
    if not 0 <= index <= length + 1:
        raise ConfigError(f"Gold codes: index {index} out of 0..{length + 1} for n={n_bits}")
    if index == 0:
        return u.copy()
    if index == 1:
        return v.copy()
    return u ^ np.roll(v, -(index - 2))


def spread(bits, code) -> np.ndarray:
    """BPSK chips (+-1 floats) of data `bits` (0/1), each bit multiplying one period of `code` (0/1)."""
    chips = bipolar(code)
    return (bipolar(bits)[:, None] * chips[None, :]).ravel()


def despread(rx_chips, code) -> np.ndarray:
    """Hard bit decisions (0/1) from received chips aligned to `code`: correlate each period, sign decides."""
    chips = bipolar(code)
    rx = np.asarray(rx_chips, dtype=float).reshape(-1, len(chips))
    return (rx @ chips < 0).astype(np.uint8)

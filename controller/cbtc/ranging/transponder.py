"""Coded train-to-train ranging (the CODIBDT and FOLOMIE radars): correlation receiver, two-way exchange, reply
data, sensor model.

Baseband model, one sample per chip (integrate-and-dump over rectangular chips of unit energy). SNR is per chip,
Ec/N0: the noise of a real sample has variance N0/2 = 1 / (2 SNR). A signal delayed by k + f chips (0 <= f < 1)
puts (1 - f) of chip j and f of chip j - 1 into each sample, so the periodic correlation with the code is a triangle
around the true delay, and the sub-chip delay is read from the peak and its larger neighbour.

Two-way exchange (the FOLOMIE radar's master/slave transponder): the follower (master) sends its ranging code; the
leader (slave) finds the code's arrival by correlation, waits a fixed turnaround, and replies with a different code of
the same Gold family; the master finds the reply's arrival and computes

    range = c * (round trip - turnaround) / 2       (modulo the code period; errors of both receivers halve)

Using a different code for the reply is what makes the master deaf to the radar echo of its own code off the leader
and to the other trains' codes (bounded Gold cross-correlation); a multipath copy of the reply can still win at low
SNR: that is a false peak, later than the truth. Seed 004 then averages the exchanges over 100 ms (`RunningMean`).

The reply carries the responder's id and status bits spread by a 31-chip code (the CODIBDT radar's C31): `reply_chips`
and `read_reply`; `ber_dsss` is that data channel's bit error rate beside theory.

`RangingSensor` is the fast model the simulator calls at 10-20 Hz: its error distribution is measured once, at
construction, by running this very receiver (cached per parameter set), not derived per call.
"""

import math
from functools import lru_cache

import numpy as np

from cbtc.errors import ConfigError
from cbtc.ranging.pn_codes import bipolar, despread, gold_code, spread

C_MPS = 299_792_458.0
RANGING_BITS = 10          # C1023 for ranging
DATA_BITS = 5              # C31 for data
MASTER_CODE = 2            # Gold family members: the follower's, the leader's reply, then other trains'
REPLY_CODE = 3
OTHER_CODES = (7, 11, 13, 17)


def chip_length_m(chip_rate_hz, wave_mps=C_MPS):
    """Range resolution (m) of one chip of round-trip delay: c / (2 chip rate)."""
    return wave_mps / (2.0 * chip_rate_hz)


def noise_sigma(snr_db):
    """Standard deviation of the real noise per sample for SNR `snr_db` per chip (Ec/N0, unit chip energy)."""
    return math.sqrt(1.0 / (2.0 * 10.0 ** (snr_db / 10.0)))


def delayed(chips, delay_chips):
    """Rows of `chips` (+-1, length N, periodic) delayed by `delay_chips` (array of T), sampled per chip: (T, N)."""
    delay = np.asarray(delay_chips, dtype=float)
    n = len(chips)
    k = np.floor(delay).astype(int)
    f = (delay - k)[:, None]
    idx = (np.arange(n)[None, :] - k[:, None]) % n
    return (1.0 - f) * chips[idx] + f * chips[(idx - 1) % n]


def find_delay_chips(rx, chips):
    """Delay (chips, in [0, N)) of `chips` in each row of `rx` (T, N): correlation peak, then sub-chip interpolation
    between the peak and its larger neighbour (exact on the noise-free triangle)."""
    n = len(chips)
    corr = np.real(np.fft.ifft(np.fft.fft(rx, axis=1) * np.conj(np.fft.fft(chips))[None, :], axis=1))
    rows = np.arange(rx.shape[0])
    k0 = np.argmax(corr, axis=1)
    r0 = corr[rows, k0]
    rp = corr[rows, (k0 + 1) % n]
    rm = corr[rows, (k0 - 1) % n]
    right = rp >= rm
    lo = np.where(right, rm, rp)
    hi = np.where(right, rp, rm)
    denom = np.maximum((r0 - lo) + (hi - lo), 1e-12)
    frac = (hi - lo) / denom
    return (k0 + np.where(right, frac, -frac)) % n


def wrap_error(est, true, n):
    """est - true on a circle of n chips, in [-n/2, n/2)."""
    return (np.asarray(est) - np.asarray(true) + n / 2.0) % n - n / 2.0


def one_way_trials(n_bits, snr_db, trials, rng, n_others=2, reflection_prob=0.0):
    """Errors (chips) of the correlation receiver finding a code at a random delay, with `n_others` other trains'
    codes at random delays and equal power, and with probability `reflection_prob` a multipath copy
    (amplitude 0.3-1.1, 1.5-6 chips later)."""
    own = bipolar(gold_code(n_bits, MASTER_CODE))
    n = len(own)
    delay = rng.uniform(0, n, trials)
    rx = _channel(own, delay, snr_db, rng, n_bits, n_others, reflection_prob)
    return wrap_error(find_delay_chips(rx, own), delay, n)


def _channel(chips, delay, snr_db, rng, n_bits, n_others, reflection_prob, echo=None):
    trials = len(delay)
    n = len(chips)
    rx = delayed(chips, delay)
    for j in range(n_others):
        other = bipolar(gold_code(n_bits, OTHER_CODES[j % len(OTHER_CODES)]))
        rx += delayed(other, rng.uniform(0, n, trials))
    if reflection_prob > 0:
        hit = rng.random(trials) < reflection_prob
        amp = np.where(hit, rng.uniform(0.3, 1.1, trials), 0.0)
        rx += amp[:, None] * delayed(chips, delay + rng.uniform(1.5, 6.0, trials))
    if echo is not None:
        echo_chips, echo_delay, echo_amp = echo
        rx += echo_amp * delayed(echo_chips, echo_delay)
    rx += rng.normal(0.0, noise_sigma(snr_db), rx.shape)
    return rx


def two_way_trials(gap_m, n_bits, snr_db, trials, rng, chip_rate_hz, turnaround_chips=300.25, n_others=2,
                   reflection_prob=0.0, echo_amp=0.0, same_code=False, wave_mps=C_MPS):
    """Measured ranges (m, array of `trials`) of two-way exchanges over a true gap `gap_m`.

    The slave's receiver error shifts its reply; the master's adds on top; the known turnaround (chips) is
    subtracted. `echo_amp`: the master also hears its own code reflected off the leader (a radar echo at the
    round-trip delay); `same_code=True` makes the leader reply with the master's own code, so the echo competes.
    """
    master = bipolar(gold_code(n_bits, MASTER_CODE))
    reply = master if same_code else bipolar(gold_code(n_bits, REPLY_CODE))
    n = len(master)
    tau = np.full(trials, gap_m / wave_mps * chip_rate_hz)       # one-way flight (chips)
    rx_slave = _channel(master, tau, snr_db, rng, n_bits, n_others, reflection_prob)
    e1 = wrap_error(find_delay_chips(rx_slave, master), tau, n)
    rt = 2.0 * tau + e1 + turnaround_chips
    echo = (master, 2.0 * tau, echo_amp) if echo_amp > 0 else None
    rx_master = _channel(reply, rt, snr_db, rng, n_bits, n_others, reflection_prob, echo)
    measured = find_delay_chips(rx_master, reply)
    one_way = ((measured - turnaround_chips) % n) / 2.0
    # unambiguous over half a code period of one-way delay; the top 10 % of it reads as a small negative range
    one_way = np.where(one_way > 0.45 * n, one_way - n / 2.0, one_way)
    return one_way * wave_mps / chip_rate_hz


def threshold_snr_db(n_bits, rng, trials=300, n_others=2, within_chips=1.0, share=0.99, snr_grid=None):
    """Lowest SNR (dB per chip) on the grid at which the receiver finds the delay within `within_chips` in at least
    `share` of `trials`, with `n_others` other codes present; and the success share at each grid point."""
    grid = np.arange(-30.0, 1.0, 1.0) if snr_grid is None else snr_grid
    shares = []
    found = None
    for snr in grid:
        err = one_way_trials(n_bits, float(snr), trials, rng, n_others)
        ok = float(np.mean(np.abs(err) <= within_chips))
        shares.append((float(snr), ok))
        if ok >= share and found is None:
            found = float(snr)
            break
    return found, shares


# --- the reply's data: responder id and status spread by a 31-chip code ----------------------------------------------

def reply_bits(responder_id, status):
    """16 bits (MSB first): responder id (0..255), status (0..255)."""
    if not (0 <= responder_id <= 255 and 0 <= status <= 255):
        raise ConfigError(f"reply: responder id and status are 0..255, got {responder_id}, {status}")
    word = (responder_id << 8) | status
    return np.array([(word >> (15 - i)) & 1 for i in range(16)], dtype=np.uint8)


def reply_chips(responder_id, status, n_bits=DATA_BITS):
    """The reply's data chips (+-1): 16 bits, each spread by the 31-chip code."""
    return spread(reply_bits(responder_id, status), gold_code(n_bits, REPLY_CODE))


def read_reply(rx_chips, n_bits=DATA_BITS):
    """(responder_id, status) from received data chips aligned to the code."""
    bits = despread(rx_chips, gold_code(n_bits, REPLY_CODE))
    word = 0
    for b in bits:
        word = (word << 1) | int(b)
    return word >> 8, word & 0xFF


def ber_theory(snr_db, spreading=31):
    """BPSK after despreading: Q(sqrt(2 Eb/N0)) with Eb/N0 = spreading * Ec/N0."""
    ebn0 = spreading * 10.0 ** (snr_db / 10.0)
    return 0.5 * math.erfc(math.sqrt(ebn0))


def ber_dsss(snr_db, n_bits_total, rng, n_bits=DATA_BITS, chunk=100_000):
    """(errors, bits) of the 31-chip DSSS BPSK data channel in AWGN at `snr_db` per chip (Ec/N0)."""
    code = gold_code(n_bits, REPLY_CODE)
    chips = bipolar(code)
    sigma = noise_sigma(snr_db)
    errors = 0
    done = 0
    while done < n_bits_total:
        m = min(chunk, n_bits_total - done)
        bits = rng.integers(0, 2, m).astype(np.uint8)
        rx = bipolar(bits)[:, None] * chips[None, :] + rng.normal(0.0, sigma, (m, len(chips)))
        errors += int(np.count_nonzero(despread(rx.ravel(), code) != bits))
        done += m
    return errors, done


# --- running mean (the FOLOMIE tunnel radar: 100 ms) ------------------------------------------------------------------

class RunningMean:
    """Mean of the values added within the last `window_s` seconds; time is passed in."""

    def __init__(self, window_s=0.1):
        self.window_s = window_s
        self._items = []

    def add(self, t_s, value):
        self._items.append((t_s, value))

    def mean(self, now_s):
        """The mean over (now_s - window_s, now_s], or None when the window is empty."""
        self._items = [(t, v) for t, v in self._items if t > now_s - self.window_s]
        if not self._items:
            return None
        return sum(v for _t, v in self._items) / len(self._items)


# --- the simulator's fast sensor model -------------------------------------------------------------------------------

@lru_cache(maxsize=16)
def _calibration(n_bits, chip_rate_hz, snr_db, reflection_prob, trials, seed):
    """Errors (m) of `trials` full two-way exchanges at a 1 m gap: the sensor's error distribution."""
    rng = np.random.default_rng(seed)
    errors = two_way_trials(1.0, n_bits, snr_db, trials, rng, chip_rate_hz, reflection_prob=reflection_prob,
                            echo_amp=1.0) - 1.0
    return np.sort(errors)


class RangingSensor:
    """The follower's coded ranging to the train ahead, as the simulator sees it.

    chip_rate_hz: 1 GHz by default (a UWB-class radio: 0.15 m of range per chip); snr_db per chip at the receiver;
    reflection_prob: share of exchanges with a strong multipath copy (a false peak when it wins); exchanges: how many
    exchanges the 100 ms running mean holds; max_range_m: beyond it (or with no train ahead) nothing answers.

    Each `measure` draws `exchanges` errors from the calibrated distribution (the real receiver's errors, measured
    once), drops those more than one chip from their median (the false peaks), and returns the mean.
    """

    def __init__(self, chip_rate_hz=1e9, snr_db=-15.0, reflection_prob=0.05, seed=0, n_bits=RANGING_BITS,
                 exchanges=10, max_range_m=5.0, calibration_trials=400, wave_mps=C_MPS):
        if chip_rate_hz <= 0 or exchanges < 1 or max_range_m <= 0 or not 0 <= reflection_prob < 1:
            raise ConfigError("ranging sensor: chip_rate_hz > 0, exchanges >= 1, max_range_m > 0 and reflection_prob "
                              f"in [0, 1) are needed; got {chip_rate_hz}, {exchanges}, {max_range_m}, "
                              f"{reflection_prob}")
        self.chip_m = chip_length_m(chip_rate_hz, wave_mps)
        self.exchanges = int(exchanges)
        self.max_range_m = max_range_m
        self.n_bits = n_bits
        self.chip_rate_hz = chip_rate_hz
        self.snr_db = snr_db
        self.reflection_prob = reflection_prob
        self._errors_m = _calibration(n_bits, float(chip_rate_hz), float(snr_db), float(reflection_prob),
                                      int(calibration_trials), int(seed))
        inliers = self._errors_m[np.abs(self._errors_m) <= self.chip_m]
        self.exchange_sigma_m = float(np.std(inliers)) if len(inliers) > 1 else self.chip_m
        self.outlier_rate = 1.0 - len(inliers) / len(self._errors_m)
        self.sigma_m = self.exchange_sigma_m / math.sqrt(self.exchanges)

    def measure(self, true_gap_m, rng, full=False):
        """(gap_m | None, quality): the averaged measured gap (m) and the share of exchanges kept (0..1).
        `full=True` runs the real correlation receiver for every exchange instead of the calibrated errors."""
        if true_gap_m is None or true_gap_m > self.max_range_m:
            return None, 0.0
        gap = max(true_gap_m, 0.0)
        if full:
            values = two_way_trials(gap, self.n_bits, self.snr_db, self.exchanges, rng, self.chip_rate_hz,
                                    reflection_prob=self.reflection_prob, echo_amp=1.0)
        else:
            values = gap + rng.choice(self._errors_m, self.exchanges)
        median = float(np.median(values))
        kept = values[np.abs(values - median) <= self.chip_m]
        quality = len(kept) / len(values)
        if quality < 0.5:
            return None, quality
        return float(np.mean(kept)), quality

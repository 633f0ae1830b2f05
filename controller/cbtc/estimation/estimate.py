"""What every position estimator gives the movement authority, and how board times map to controller time."""

from cbtc.frozen import frozen_value
from cbtc.protocol import wire
from cbtc.railway.geometry import circular_offset_m

wrap_diff = wire.wrap_diff   # named once: a module's attribute is looked up at every use


def span_offsets_m(layout, span, s_m: float):
    """A span of track positions (low, high) as (behind <= 0, ahead >= 0) offsets from position `s_m` on `layout`,
    the short way round on a loop: how far behind and ahead of `s_m` it reaches (0 where it does not)."""
    low_m, high_m = (circular_offset_m(layout.wrap(x), layout.wrap(s_m), layout.loop_length_m) for x in span)
    return min(0.0, low_m), max(0.0, high_m)


DECLARED_CARRY_SHARE = 0.05   # of the odometer's travel since a declaration: the doubt of its scale


def declared_at(declared, d_m: float):
    """(s_m, tol_m) of a declaration (s_m, tol_m, odometer m when declared, or None: the train stood) carried along by
    the odometer to `d_m`: the train ran on since, and the tolerance widens by the scale's doubt over that run."""
    s_m, tol_m, odo_m = declared
    if odo_m is None:
        return s_m, tol_m
    run_m = d_m - odo_m
    return s_m + run_m, tol_m + DECLARED_CARRY_SHARE * abs(run_m)


@frozen_value
class Estimate:
    """A train's head position and speed at controller time `t_s`, with 1-sigma uncertainties.

    `s_m` is wrapped onto the layout; `data_t_s` is the controller time of the newest measurement behind it,
    so `t_s - data_t_s` is the age of the data. `ahead_m` and `behind_m` (>= 0) say how much further ahead of or
    behind `s_m` the train may plausibly be beyond its sigma, while its sensors disagree (an IPS run that the filter
    gates: multipath on one side, wheel slip on the other); the authority takes them off in full.
    """

    s_m: float
    v_mps: float
    sigma_s_m: float
    sigma_v_mps: float
    t_s: float
    data_t_s: float
    ahead_m: float = 0.0
    behind_m: float = 0.0

    @property
    def age_s(self) -> float:
        return self.t_s - self.data_t_s


class BoardClock:
    """Maps a board's uptime (ms, modulo 2^30 on the wire) to controller time (s) without clock synchronisation.

    Board times are unwrapped against the newest one observed (wire.wrap_diff), so a board up for months maps as on
    its first day. offset = min over reports of (receive time - board time): the least-delayed report bounds the
    offset from above, so board times convert to controller times that are never later than the truth by more than
    the one-way latency of that best report. Pure: receive times are passed in.
    """

    def __init__(self):
        self.offset_s = None
        self._ref_ms = None          # the newest board time observed, as on the wire, and its unwrapped value
        self._ref_unwrapped_ms = 0

    def board_s(self, board_ms: int) -> float:
        """`board_ms` (a wire time near the newest observed) on the board's own unwrapped time line (s)."""
        if self._ref_ms is None:
            raise ValueError("BoardClock: no report observed yet")
        return (self._ref_unwrapped_ms + wrap_diff(board_ms, self._ref_ms)) / 1000.0

    def observe(self, board_ms: int, recv_s: float) -> None:
        if self._ref_ms is None:
            self._ref_ms, self._ref_unwrapped_ms = board_ms, board_ms
        else:
            ahead_ms = wrap_diff(board_ms, self._ref_ms)
            if ahead_ms > 0:
                self._ref_ms, self._ref_unwrapped_ms = board_ms, self._ref_unwrapped_ms + ahead_ms
        candidate = recv_s - self.board_s(board_ms)
        if self.offset_s is None or candidate < self.offset_s:
            self.offset_s = candidate

    def to_controller_s(self, board_ms: int) -> float:
        if self.offset_s is None:
            raise ValueError("BoardClock: no report observed yet")
        return self.board_s(board_ms) + self.offset_s

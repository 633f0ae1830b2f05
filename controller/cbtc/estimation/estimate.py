"""What every position estimator gives the movement authority, and how board times map to controller time."""

from dataclasses import dataclass


@dataclass(frozen=True)
class Estimate:
    """A train's head position and speed at controller time `t_s`, with 1-sigma uncertainties.

    `s_m` is wrapped onto the layout; `data_t_s` is the controller time of the newest measurement behind it,
    so `t_s - data_t_s` is the age of the data.
    """

    s_m: float
    v_mps: float
    sigma_s_m: float
    sigma_v_mps: float
    t_s: float
    data_t_s: float

    @property
    def age_s(self) -> float:
        return self.t_s - self.data_t_s


class BoardClock:
    """Maps a board's uptime (ms) to controller time (s) without clock synchronisation.

    offset = min over reports of (receive time - board time): the least-delayed report bounds the offset from above,
    so board times convert to controller times that are never later than the truth by more than the one-way
    latency of that best report. Pure: receive times are passed in.
    """

    def __init__(self):
        self.offset_s = None

    def observe(self, board_ms: int, recv_s: float) -> None:
        candidate = recv_s - board_ms / 1000.0
        if self.offset_s is None or candidate < self.offset_s:
            self.offset_s = candidate

    def to_controller_s(self, board_ms: int) -> float:
        if self.offset_s is None:
            raise ValueError("BoardClock: no report observed yet")
        return board_ms / 1000.0 + self.offset_s

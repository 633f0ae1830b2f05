"""Truth of virtual trains: which train is ahead of which, collisions, and how far each board moved past its end
of authority. The recorder of a simulated run and the virtual trains on a real broker both count collisions here."""

from cbtc.railway.ahead import trains_ahead


def train_ahead(layout, heads_m):
    """{i: j}: the index of the train ahead of train i, for trains with heads at `heads_m` (on a line, the front train
    has none): railway's one answer to what lies ahead."""
    return trains_ahead(heads_m, layout.closed)


def head_inside(layout, head_s_m, ahead_tail_s_m, ahead_length_m) -> bool:
    """A head inside the span of the train ahead: a collision (on a line, a head still behind that tail is not)."""
    return 0.0 <= layout.ahead_m(ahead_tail_s_m, head_s_m) <= ahead_length_m


class TruthMonitor:
    """Collisions counted from the trains' true positions, as the recorder of a simulated run counts them: a collision
    starts when a train's head enters the span of the train ahead. And how far each board's odometer ever moved past
    the end of authority it held at the time (`moved_past_eoa_mm`): an end of authority set behind a standing train
    (an estimate corrected by a few mm) is no overrun unless the train then moves."""

    def __init__(self, layout, trains):
        self.layout = layout
        self.trains = trains
        self.collisions = [0] * len(trains)
        self._inside = [False] * len(trains)
        self.moved_past_eoa_mm = [0] * len(trains)
        self._odo_mm = [None] * len(trains)
        self._sliding = [False] * len(trains)

    def rebooted(self, i) -> None:
        """Train i's board has just restarted: it brakes at once, and its slide to a stop, with the new boot's odometer
        from zero and no authority yet, is no overrun."""
        self._sliding[i] = True
        self._odo_mm[i] = None

    def sample(self, _now_s=None) -> None:
        trains = self.trains
        for i, train in enumerate(trains):
            if self._sliding[i]:
                self._sliding[i] = train.v_mps > 0
                continue
            odo_mm, before_mm = train.obu.odo_mm, self._odo_mm[i]
            if before_mm is not None and odo_mm > before_mm:
                past_mm = odo_mm - max(train.obu.eoa_mm, before_mm)
                if past_mm > 0:
                    self.moved_past_eoa_mm[i] += past_mm
            self._odo_mm[i] = odo_mm
        if len(trains) < 2:
            return
        for i, j in train_ahead(self.layout, [t.head_s for t in trains]).items():
            ahead = trains[j]
            inside = head_inside(self.layout, trains[i].head_s, ahead.tail_s, ahead.length_m)
            if inside and not self._inside[i]:
                self.collisions[i] += 1
            self._inside[i] = inside

    def train_summary(self, i) -> dict:
        train = self.trains[i]
        obu = train.obu
        return {
            "train": train.train_id,
            "head_s_m": round(train.head_s, 4),
            "distance_m": round(train.travelled_m, 4),
            "laps": int(train.travelled_m // self.layout.length_m) if self.layout.closed else 0,
            "v_mps": round(train.v_mps, 4),
            "mode": obu.mode,
            "odo_mm": obu.odo_mm,
            "eoa_mm": obu.eoa_mm,
            "sid": obu.sid,
            "cseq": obu.cseq,
            "commands_rejected_onboard": obu.rejected,
            "last_reject": obu.last_reject,
            "faults": list(obu.faults),
            "collisions": self.collisions[i],
            "moved_past_eoa_mm": self.moved_past_eoa_mm[i],
            "trips": obu.trips,
            "connected": train.client.connected,
        }

    def summary(self, now_s: float) -> dict:
        trains = [self.train_summary(i) for i in range(len(self.trains))]
        return {"t_s": round(now_s, 3), "layout": self.layout.name, "trains": trains,
                "collisions": sum(self.collisions)}

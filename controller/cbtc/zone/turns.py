"""Reversal on a line: a train at the end of a leg of its itinerary (cbtc.railway.legs) turns onto the next leg.

It turns once it has stood for TURN_STILL_S within END_M of its leg's end (a terminus platform, or the buffer stop)
with no stop left on the leg, and then HOLD_S with no authority (a board still creeps onto its last end of authority
and would refuse a turn). Nothing it held survives the turn: its routes are released, its authority withdrawn
(its span stays an obstacle to every other train until it is located again), and it is located afresh on the new
leg's frame, where its tail was declared as its head's position by the zone's own estimate, covering that
estimate's uncertainty, for the IPS or a balise to confirm. Its commands then name the new direction (`dir`), which
its board takes standing (docs/protocol.md).

A zone that has never seen a train (just started, or handed it) does not know which way it faces: it takes the way
from the board's first report (`dir`) and puts the train on its next leg that runs that way (`Turns.face`), so that
it never turns a train it did not bring to a leg's end. A train it knew whose board restarts (facing forward) keeps
its leg, and the board is told its way back, standing.
"""

import logging

from cbtc.railway.legs import next_leg, turned_head_s
from cbtc.zone.stations import NO_MORE_STOPS

log = logging.getLogger("cbtc.zone")
TURN_STILL_S = 1.0   # standing this long (by the zone's clock; the board's own rule is half a second)
HOLD_S = 0.6         # then held this long with no authority, so the board's last one lapses before it is told to turn
END_M = 0.5          # this near its leg's end


class Turns:
    def __init__(self, routes, estimators, k_sigma):
        self.routes = routes           # the zone's NetworkRoutes
        self.estimators = estimators   # makes the fresh estimator of a turned train
        self.k_sigma = k_sigma
        self.count = 0
        self._driven_s = {}            # train -> report time of its newest report that moved or drove it

    def due(self, st, now_s):
        """Whether `st`'s train has come to the end of its leg and stands there, nothing left to do on it."""
        if not st.setup.legs or st.report is None or not st.estimator.localized:
            return False
        report = st.report   # standing and undriven (the board takes a turn only so) for TURN_STILL_S
        if report["v_mmps"] or report["duty"] or st.odo_moved or st.train_id not in self._driven_s:
            self._driven_s[st.train_id] = st.report_t_s   # (first seen: it stands from then on, at the earliest)
        if st.dwell_until_s is not None or (st.stops and st.next_stop != NO_MORE_STOPS):
            return False
        if now_s - self._driven_s[st.train_id] < TURN_STILL_S or \
                st.frame.length_m - st.newest_estimate().s_m > END_M:
            st.turn_at_s = None
            return False
        if st.turn_at_s is None:
            st.turn_at_s = now_s + HOLD_S   # held from now (situations.own_hold)
        return now_s >= st.turn_at_s

    def turn(self, st, now_s):
        """Put `st`'s train on its next leg, standing where it is, the other way round."""
        legs = st.setup.legs
        old, k = legs[st.leg], (st.leg + 1) % len(legs)
        new = legs[k]
        est = st.newest_estimate()
        head_s = turned_head_s(old, new, est.s_m, st.setup.profile.length_m)
        tol_m = self.k_sigma * est.sigma_s_m + est.ahead_m + est.behind_m + 0.02
        self.routes.turn(st, new.route, now_s)
        _put_on(st, k)
        estimator = self.estimators.fresh(st)
        estimator.declare_position(head_s, tol_m)
        if hasattr(estimator, "carry_wheel"):   # the same wheel: its scale as the balises vouched for it
            estimator.carry_wheel(st.estimator.wheel_band)
        st.relocate(estimator)
        self.count += 1
        log.info("train %s: reversed at the end of its leg, onto %s (head %.3f m, within %.3f m)", st.train_id,
                 new.frame.name, head_s, tol_m)

    def face(self, st, report):
        """The first report this zone takes of `st`'s train on a line: the train is put on its next leg (from the
        one it is on) that runs the way the board drives, located afresh on it, unless its leg runs that way."""
        st.faced = True
        legs, back = st.setup.legs, report.get("dir", 0) == 1
        if legs[st.leg].backwards == back:
            return
        k = next_leg(legs, st.leg, back)
        if k is None:   # every leg runs the other way: the board is told the leg's way, standing
            return
        _put_on(st, k)
        self.routes.frames[st.train_id] = legs[k].route   # it holds no route yet: this zone has not commanded it
        st.relocate(self.estimators.fresh(st))
        log.info("train %s: its board drives %s: on %s", st.train_id, "backwards" if back else "forward",
                 legs[k].frame.name)


def _put_on(st, k):
    """`st`'s train on leg `k` of its plan: its frames, stops and direction those of that leg, no stop under way."""
    leg = st.setup.legs[k]
    st.leg, st.turn_at_s, st.next_stop, st.leaving = k, None, None, None
    st.frame, st.sensor_frame, st.stops, st.track_m = leg.frame, leg.sensors, leg.stops, leg.frame.length_m
    st.travel_dir = 1 if leg.backwards else 0

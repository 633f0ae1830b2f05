"""The zone's obstacles: what stands on its track that it cannot command, where its reports put it, and the
authority each train loses to it.

A board under an id the zone does not know, the second of two boards under one id (or a replay of one), and the
place of a car come off a train are each an Obstacle (cbtc.zone.obstacles). Their reports cannot be authenticated,
but an obstacle only takes authority away: it is kept where its reports put it (an IPS fix, a balise read), every
train behind it held short of it, and every train while one is seen nowhere.
"""

import logging

from cbtc.protocol import unsealed, wire
from cbtc.railway.balise import BaliseReader
from cbtc.railway.ips_frame import ips_to_track
from cbtc.zone.boots import TWIN_ALIVE_S
from cbtc.zone.obstacles import Obstacle, room_m
from cbtc.zone.refusals import UNKNOWN

log = logging.getLogger("cbtc.zone")
SEEN_IPS_M = 0.45   # an obstacle's IPS fix puts its head within this either way: the IPS's lasting bias (0.3 m,
#                     UkfParams.ips_bias_m) and 3 sigma of its noise
SEEN_TAG_M = 0.05   # ... a balise read of it: the reader's range and a tag's placement


class ObstacleWatch:
    def __init__(self, layout, profiles, params, refusals):
        self.layout = layout
        self.params = params
        self.refusals = refusals
        self.obstacles = {}        # name -> Obstacle
        self.parted = set()        # trains whose train line opened: their car's place is an obstacle
        # where an obstacle's tag reads put it; on a track network (layout None) an obstacle is placed nowhere, so
        # while one is known every train is held
        self._balises = None if layout is None else BaliseReader(layout)
        self._stranger_length_m = max(p.length_m for p in profiles)   # an unknown train is as long as the longest,
        self._stranger_v_mps = 1.5 * max(p.v_noload_mps for p in profiles)   # and no faster than half again theirs

    def stranger(self, train_id, topic, payload, recv_s):
        """A report under an id this zone does not know: a board on the track it cannot command."""
        try:
            report = unsealed.peek_report(topic, payload)
        except wire.WireError as exc:
            self.refusals.note(UNKNOWN, "report", f"train {train_id!r} is not in this zone ({exc.reason})", recv_s)
            return
        name = f"unknown board {train_id}"
        obstacle = self.obstacles.get(name)
        if obstacle is None:
            obstacle = self.obstacles[name] = Obstacle(name, self._stranger_length_m, self._stranger_v_mps)
            log.error("a board reports as train %s, which is not in this zone: it is an obstacle where its reports put "
                      "it (every train behind it is held short of it, and every train while they place it nowhere); "
                      "configure it (a train of the zone) or take it off the track and restart the zone", train_id)
        self._sight(obstacle, report, recv_s)

    def _sight(self, obstacle, report, recv_s):
        """Where `report` puts `obstacle`'s head: its IPS fix, its balise reads."""
        obstacle.hear(recv_s)
        if self.layout is None:
            return
        fix = report["ips"]
        if fix is not None:
            x_m, y_m = ips_to_track(fix[1] / 1000.0, fix[2] / 1000.0, self.layout.ips)
            s_m = float(self.layout.project(x_m, y_m))
            obstacle.see(recv_s, s_m - SEEN_IPS_M, s_m + SEEN_IPS_M)
        for entry in report["tags"]:
            s_m = self._balises.position_m(entry[0], entry[4] if len(entry) > 4 else None)
            if s_m is not None:
                obstacle.see(recv_s, s_m - SEEN_TAG_M, s_m + SEEN_TAG_M)

    def other_boot(self, state, report, recv_s, proven):
        """An authenticated report of a boot under `state`'s id that is not the train's current one and moves nothing
        forward: a second board, or a replay. Either way something may stand where it says: an obstacle, which lapses
        when that boot falls silent for BootTracker's TWIN_ALIVE_S, until it is `proven` a second board
        (BootTracker.second_board): then the train is held and the obstacle stays."""
        name = self._other_boot_name(state, report["boot"])
        obstacle = self.obstacles.get(name)
        if obstacle is None:
            profile = state.setup.profile
            obstacle = self.obstacles[name] = Obstacle(name, profile.length_m, 1.5 * profile.v_noload_mps,
                                                       lapse_s=TWIN_ALIVE_S)
        self._sight(obstacle, report, recv_s)
        if proven and obstacle.lapse_s is not None:
            obstacle.lapse_s = None
            log.error("two boards report as train %s (boots %d and %d): the train is held, and the board of boot %d "
                      "is an obstacle where its reports put it; take one of them off the track (or flash it with its "
                      "own id and key) and restart the zone", state.train_id, state.boots.boot, report["boot"],
                      report["boot"])

    def boot_is_train(self, state, boot):
        """The boot `state`'s train goes on with is the train itself, no obstacle."""
        self.obstacles.pop(self._other_boot_name(state, boot), None)

    @staticmethod
    def _other_boot_name(state, boot):
        return f"second board of {state.train_id} (boot {boot})"

    def nowhere(self, state, now_s):
        """The name of an obstacle not yet seen anywhere (it may be on any track: every train is held, as while a
        train of the zone is not located), or None; lapsed obstacles are dropped."""
        for obstacle in list(self.obstacles.values()):
            if obstacle.lapsed(now_s):
                del self.obstacles[obstacle.name]
            elif not obstacle.seen and obstacle.owner != state.train_id:
                return obstacle.name
        return None

    def clear_of(self, state, auth, now_s):
        """`auth` cut short of every obstacle seen ahead of `state`'s train (its margin and k sigma of its own estimate
        off)."""
        if not self.obstacles:
            return auth
        est = state.newest_estimate()
        layout = self.layout
        front_s = layout.wrap(est.s_m + est.ahead_m + self.params.k_sigma * est.sigma_s_m)
        for obstacle in list(self.obstacles.values()):
            if obstacle.lapsed(now_s):
                del self.obstacles[obstacle.name]
                continue
            if obstacle.owner == state.train_id:
                continue
            span = obstacle.span(layout, now_s)
            if span is None:   # not seen yet: the caller holds every train
                continue
            distance_m = room_m(layout, front_s, span) - self.params.margin_m
            if distance_m < auth.distance_m:
                auth = auth.cut_to(distance_m, obstacle.name)
        return auth

    def car_come_off(self, state, just_now, recv_s):
        """The train line opened: the rear-most tail of the newest picture from before stays occupied, an obstacle
        to every train (the board brakes its own train for good). Told after the fact (a zone started since), the
        car may be up to a train's length behind the tail: that stays occupied. Not located, it waits."""
        if state.report is None or not state.estimator.localized or state.newest_estimate() is None:
            return
        picture = state.picture()
        length_m = state.setup.profile.length_m
        rear_m = picture.s_m - length_m - picture.behind_m - self.params.k_sigma * picture.sigma_s_m
        low_m = rear_m if just_now else rear_m - length_m
        name = f"a car come off {state.train_id}"
        obstacle = self.obstacles[name] = Obstacle(name, 0.0, 0.0)
        if self.layout is not None:
            obstacle.see(recv_s, low_m, rear_m)
        self.parted.add(state.train_id)
        log.error("train %s: its train line opened (a car came off?): its board brakes it for good, and the place of "
                  "its tail stays occupied until this zone restarts; recouple the car, then reboot the board",
                  state.train_id)

"""The zone controller: reports in, estimates, movement authorities and station stops, commands out.

Thin shell around the pure parts: it talks to a bus client (mock broker or a real MQTT broker: the same interface),
reads time only from the `now_fn` it is given, and keeps per-train state. Each report is answered at once (and each
cycle, 10 Hz by default, covers the trains whose reports are missing): it orders the trains along the track, asks the
authority policy how far each may go, converts that limit (the end of authority, supervised on board by the trip
curve) and the next station stop (a service target) into the train's own odometer frame and publishes a sealed
command. A train whose follower is held by it is asked for faster reports (`AuthorityParams.fast_report_ms`): its
follower's authority rests on the age of that data. The controller grants fast reports within the report rate it is
sized for (`report_budget_hz`), to the trains whose followers are nearest their limits first.

A train gets no authority while any configured train is unlocated (it could be anywhere) or its reports do not yet
answer this controller (cbtc.zone.boots: they could be replayed), and no extension while the data of the train ahead
is stale. Reports that fail validation, come from unknown trains or do not move a train's picture forward are logged
and dropped.
"""

import logging
import random
from dataclasses import dataclass, field

from cbtc.authority.rules import AuthorityParams, following_reach_m
from cbtc.estimation.estimate import BoardClock
from cbtc.firmware import obu
from cbtc.protocol import wire
from cbtc.railway.physics import braking_distance_m
from cbtc.railway.train_profile import TrainProfile
from cbtc.zone.boots import BootTracker

log = logging.getLogger("cbtc.zone")
DEAF_WARN_S = 2.0   # a train whose reports do not answer our commands for this long is named in a warning
ENCODER_FAULTS = frozenset(("enc_fail", "enc_stall"))   # its odometer cannot be trusted: locate the train afresh


@dataclass
class TrainSetup:
    """What the controller is told about a train: identity, key, physics, and where it stops."""

    train_id: str
    key: bytes
    profile: TrainProfile = field(default_factory=TrainProfile)
    stops: tuple = ()                   # station names this train stops at
    dwell_s: tuple = (1.0, 3.0)         # dwell time drawn uniformly from this range at each stop


class TrainState:
    """The controller's picture of one train."""

    def __init__(self, setup: TrainSetup, estimator):
        self.setup = setup
        self.estimator = estimator
        self.clock = BoardClock()
        self.report = None           # newest accepted report (dict)
        self.report_recv_s = None
        self.report_t_s = None       # controller time at which the board sampled it
        self.boots = BootTracker()   # which reports move the picture forward; has the board answered us
        self.next_stop = None        # station name or None
        self.dwell_until_s = None
        self.dwells = 0
        self.limit_s = None          # current authority limit along the track (m), for supervision
        self.safe_m = None           # distance the safety limit allowed at the last command (m)
        self.eoa_mm = None
        self.cmd_seq = 0
        self.reports_rejected = 0
        self.last_reject = ""
        self.stop_overruns = 0
        self.restarts = 0
        self.answered_s = None       # controller time of the last command sent to this train
        self.fast_until_s = -1.0     # until then this train is asked for fast reports (a train behind follows it)
        self.fast_need_m = 0.0       # the authority left to that follower (m): the less, the more it needs them
        self.leader_data_t_s = None  # sample time of the train-ahead data the last authority rests on (moving block)
        self.sigma_m = None          # combined 1-sigma of both estimates taken off that authority (k of them)
        self.rng_gap = None          # (controller time s, gap m) last measured by the train's own ranging
        self.gap_alarm = False       # the measured gap disagrees with the estimated one ("picture disagrees")
        self.gap_alarms = 0
        self.deaf_since_s = None     # since when this train's reports have not answered our commands
        self.encoder_failed = False  # its last report named an encoder fault: located afresh once it is healthy
        self.encoder_failures = 0

    @property
    def train_id(self):
        return self.setup.train_id

    def restart(self, estimator):
        """The board rebooted: forget its clock, odometer frame and position; it must be located again."""
        self.relocate(estimator)
        self.clock = BoardClock()
        self.report = None
        self.restarts += 1

    def relocate(self, estimator):
        """Forget where the train is and its odometer's frame: it gets no authority until `estimator` locates it."""
        self.estimator = estimator
        self.eoa_mm = None
        self.limit_s = None


class ZoneController:
    def __init__(self, layout, trains, client, now_fn, policy, params: AuthorityParams = None,
                 estimator_factory=None, cycle_s: float = 0.1, zone_id: str = "zc1", seed: int = 0,
                 event_driven: bool = True, report_budget_hz: float = 400.0):
        if not trains:
            raise ValueError("zone controller: no trains configured")
        self.layout = layout
        self.client = client
        self.now_fn = now_fn
        self.policy = policy
        self.params = params or AuthorityParams()
        self.cycle_s = cycle_s
        self.event_driven = event_driven
        self.zone_id = zone_id
        self._rng = random.Random(seed)
        self.session_id = self._rng.randrange(1, 2 ** 31 - 1)
        if estimator_factory is None:
            from cbtc.estimation.ukf_estimator import UkfEstimator as estimator_factory
        self._estimator_factory = estimator_factory
        self.trains = {}
        for setup in trains:
            wire.check_train_id(setup.train_id)
            if setup.train_id in self.trains:
                raise ValueError(f"zone controller: train id {setup.train_id!r} configured twice")
            for name in setup.stops:
                layout.station(name)  # raises LayoutError naming the known stations
            self.trains[setup.train_id] = TrainState(setup, estimator_factory(layout, setup.profile))
        self.unknown_reports = 0
        self.invalid_reports = 0
        self.cycles = 0
        self.ranging_sigma_m = 0.02   # 1-sigma of a measured gap (cbtc.ranging.transponder.RangingSensor.sigma_m)
        self.use_measured_gap = True  # False: measured gaps only raise the alarm, the authority ignores them
        self.on_command = None        # callable(state, now_s) after each command is published (supervision, tests)
        # Reports a second this controller is sized for (measured with `cbtc bench latency`: 20 trains at 20 Hz on
        # two shared cores, its own compute p99 under 2.5 ms a report; 1000 a second saturated it). Every train
        # reports at the board's own rate; what is left pays for fast reports, each fast train costing the difference.
        base_hz = 1000.0 / obu.DEFAULTS["report_ms"]
        extra_hz = 1000.0 / self.params.fast_report_ms - base_hz
        spare_hz = report_budget_hz - base_hz * len(self.trains)
        self.fast_slots = max(0, int(spare_hz // extra_hz)) if extra_hz > 0 else len(self.trains)

    # --- shell: bus ----------------------------------------------------------------------------------------------

    def start(self):
        """Subscribe to reports and announce the controller (retained)."""
        self.client.subscribe(wire.REPORT_FILTER, self.on_report)
        self.client.publish(wire.topic_zone_status(self.zone_id), b"online", retain=True)

    def on_report(self, topic, payload):
        recv_s = self.now_fn()
        try:
            train_id = wire.train_id_of(topic)
        except wire.WireError as exc:
            self.invalid_reports += 1
            log.warning("dropped message on %s: %s", topic, exc.reason)
            return
        state = self.trains.get(train_id)
        if state is None:
            self.unknown_reports += 1
            log.warning("dropped report from unknown train %r on %s: configure it or remove the board", train_id, topic)
            return
        try:
            report = wire.decode_report(state.setup.key, topic, payload)
        except wire.WireError as exc:
            state.reports_rejected += 1
            state.last_reject = exc.reason
            self.invalid_reports += 1
            log.warning("dropped report of train %s: %s", train_id, exc.reason)
            return
        reason = state.boots.refusal(report, recv_s)
        if reason:
            state.reports_rejected += 1
            state.last_reject = reason
            log.warning("dropped report of train %s: %s", train_id, reason)
            return
        if state.boots.accept(report, recv_s, self.session_id):
            # a new boot: the board restarted; its clock, odometer and sequence began again
            log.warning("train %s restarted (boot %d): locating it afresh", train_id, report["boot"])
            state.restart(self._estimator_factory(self.layout, state.setup.profile))
        self._watch_answers(state, recv_s)
        state.clock.observe(report["t_ms"], recv_s)
        if ENCODER_FAULTS.intersection(report["flt"]):
            # the board has tripped and its odometer may be anywhere: a fresh estimator, fed from the first healthy
            # report on, locates the train again before it gets authority
            if not state.encoder_failed:
                state.encoder_failed = True
                state.encoder_failures += 1
                log.warning("train %s: its encoder failed (%s): it gets no authority until it reports healthy and "
                            "is located again; every train is held meanwhile", train_id,
                            ", ".join(sorted(ENCODER_FAULTS.intersection(report["flt"]))))
            state.relocate(self._estimator_factory(self.layout, state.setup.profile))
        else:
            state.encoder_failed = False
            state.estimator.on_report(report, state.clock)
        state.report = report
        state.report_recv_s = recv_s
        state.report_t_s = state.clock.to_controller_s(report["t_ms"])
        if report.get("rng") is not None:
            state.rng_gap = (state.clock.to_controller_s(report["rng"][0]), report["rng"][1] / 1000.0)
        if self.event_driven and state.estimator.localized:
            self._answer(state, recv_s)

    def _watch_answers(self, state, recv_s):
        """Warn once when a train's reports have not answered our commands for DEAF_WARN_S: the zone holds every
        train meanwhile, and the user needs to know which board and why."""
        if state.boots.answered or state.answered_s is None:
            state.deaf_since_s = None
        elif state.deaf_since_s is None:
            state.deaf_since_s = recv_s
        elif recv_s - state.deaf_since_s >= DEAF_WARN_S:
            log.warning("train %s: its reports have not answered this controller's commands for %.0f s, so no train "
                        "gets authority; check that its board has the same key as the controller and that no other "
                        "controller commands it (or its reports are replayed)", state.train_id,
                        recv_s - state.deaf_since_s)
            state.deaf_since_s = float("inf")   # said once, until it answers again

    # --- the cycle ---------------------------------------------------------------------------------------------------

    def located(self):
        """Train states with a position estimate, ordered by head position along the track."""
        found = [st for st in self.trains.values() if st.report is not None and st.estimator.localized]
        return sorted(found, key=lambda st: st.estimator.estimate(st.report_t_s).s_m)

    def _all_located(self, located):
        """Every train located, and answering this controller (its reports echo our session): a replayed stream of
        reports never answers, so no authority rests on it."""
        return len(located) == len(self.trains) and all(st.boots.answered for st in located)

    def cycle(self, now_s: float):
        """Compute and publish a command for every train that has reported. In event-driven mode a train answered
        since the previous cycle is skipped: the cycle only covers trains whose reports did not arrive."""
        self.cycles += 1
        located = self.located()
        all_located = self._all_located(located)
        for i, state in enumerate(located):
            if self.event_driven and state.answered_s is not None and now_s - state.answered_s < self.cycle_s:
                continue
            leader = located[(i + 1) % len(located)] if len(located) > 1 else None
            self._update(state, leader, all_located, now_s)

    def _update(self, state, leader, all_located, now_s):
        stop_m = None
        if all_located:
            safe_m, v_cap_mps, acc_mps2, dec_mps2 = self.policy.authority(self, state, leader, now_s)
            stop_m = self._station_stop(state, now_s)
            if leader is not None and safe_m < following_reach_m(state.setup.profile):
                # this train is held by the one ahead: ask that one for fast reports, for a while
                leader.fast_until_s = now_s + self.params.fast_hold_s
                leader.fast_need_m = safe_m
        else:
            safe_m = None
            v_cap_mps = 0.0
            acc_mps2 = dec_mps2 = state.setup.profile.beta_s_mps2
        self._command(state, safe_m, stop_m, v_cap_mps, acc_mps2, dec_mps2, now_s)
        state.answered_s = now_s

    def _answer(self, state, now_s):
        """Event-driven: a fresh report is answered at once, and it extends its follower's authority at once too."""
        located = self.located()
        if state not in located:
            return
        all_located = self._all_located(located)
        i = located.index(state)
        leader = located[(i + 1) % len(located)] if len(located) > 1 else None
        self._update(state, leader, all_located, now_s)
        if all_located and len(located) > 1:
            self._update(located[i - 1], state, True, now_s)

    def _station_stop(self, state, now_s):
        """Distance (m) to the next scheduled stop, or None (no stop to make now); runs the dwell clock."""
        stops = state.setup.stops
        if not stops:
            return None
        est = state.estimator.estimate(state.report_t_s)
        if state.next_stop is None:
            state.next_stop = self._next_station(est.s_m, stops, at_station_ok=True)
        station = self.layout.station(state.next_stop)
        to_stop_m = self._signed_ahead(est.s_m, station.s_m)
        standing = state.report["v_mmps"] == 0
        if state.dwell_until_s is not None:
            if now_s >= state.dwell_until_s:
                state.dwell_until_s = None
                state.dwells += 1
                state.next_stop = self._next_station(station.s_m + 0.01, stops)
                return None
            return to_stop_m
        if standing and abs(to_stop_m) <= station.window_m:
            low, high = state.setup.dwell_s
            state.dwell_until_s = now_s + self._rng.uniform(low, high)
            return to_stop_m
        if to_stop_m < -station.window_m:
            # passed the stop point beyond its window: count it and move on rather than reverse
            state.stop_overruns += 1
            log.warning("train %s overran station %s by %.3f m", state.train_id, station.name, -to_stop_m)
            state.next_stop = self._next_station(station.s_m + 0.01, stops)
            return None
        return to_stop_m

    def _signed_ahead(self, from_s, to_s):
        """Forward distance from `from_s` to `to_s`; on a loop, a point up to 1 m behind is negative."""
        ahead = self.layout.ahead_m(from_s, to_s)
        if self.layout.closed and ahead > self.layout.length_m - 1.0:
            ahead -= self.layout.length_m
        return ahead

    def _next_station(self, s_m, stops, at_station_ok=False):
        """The first station in `stops` ahead of `s_m` along the track; with `at_station_ok`, a station whose stop
        window holds `s_m` (a train that starts at a platform dwells there first)."""
        def distance(name):
            station = self.layout.station(name)
            if at_station_ok and abs(self._signed_ahead(s_m, station.s_m)) <= station.window_m:
                return 0.0
            return self.layout.ahead_m(s_m, station.s_m)
        return min(stops, key=distance)

    def _command(self, state, safe_m, stop_m, v_cap_mps, acc_mps2, dec_mps2, now_s):
        """Publish the command for the end of authority `safe_m` metres ahead (None: none granted: stop) and the
        service stop target `stop_m` metres ahead (None: none); the limit is kept as `limit_s` on the track for
        supervision."""
        report = state.report
        state.safe_m = safe_m
        # a low bound of the encoder's scale (odometer m per true m): a wheel that reads short must not carry the
        # train past its limit; the board's braking curves use it too (odo_mm_per_m)
        scale_low = state.estimator.odometer_per_m_low(self.params.k_sigma)
        if safe_m is None:
            # no picture of every train: stop now at service rate; the authority never extends
            v_mps = max(0.0, report["v_mmps"] / 1000.0)
            brake_m = v_mps * state.setup.profile.reaction_s + braking_distance_m(v_mps, dec_mps2)
            eoa_mm = report["odo_mm"] + int(brake_m * 1000.0)
        else:
            eoa_mm = report["odo_mm"] + int(safe_m * scale_low * 1000.0)   # metres along the track into odometer mm
        if state.eoa_mm is not None and (safe_m is None or self._leader_stale(state, now_s)):
            eoa_mm = min(eoa_mm, state.eoa_mm)
        state.eoa_mm = eoa_mm
        # a stop target is service, not safety: the best estimate of the scale, and never beyond the end of authority
        stop_mm = eoa_mm if stop_m is None else \
            min(eoa_mm, report["odo_mm"] + int(round(stop_m * state.estimator.odometer_per_m_low(0.0) * 1000.0)))
        est = state.estimator.estimate(state.report_t_s)
        if est is None:
            state.limit_s = None
        else:
            limit_mm = eoa_mm - report["odo_mm"] if safe_m is None else safe_m * 1000.0
            state.limit_s = self.layout.wrap(est.s_m + limit_mm / 1000.0)
        state.cmd_seq = wire.wrap_add(state.cmd_seq, 1)
        rpt_ms = self.params.fast_report_ms if self._fast_reports(state, now_s) else 0
        payload = wire.encode_command(
            state.setup.key, state.train_id, report["boot"], state.cmd_seq, self.session_id, report["seq"],
            int(max(0.0, v_cap_mps) * 1000), eoa_mm, int(self.params.ttl_s * 1000),
            max(1, int(acc_mps2 * 1000)), max(1, int(dec_mps2 * 1000)), stop_mm, rpt_ms,
            max(wire.ODO_MM_PER_M_MIN, min(wire.ODO_MM_PER_M_MAX, int(scale_low * 1000.0))))   # floored: the safe side
        self.client.publish(wire.topic_command(state.train_id), payload)
        if self.on_command is not None:
            self.on_command(state, now_s)

    def _fast_reports(self, state, now_s):
        """True when `state`'s train is to report fast: the policy's authority rests on train reports (moving block;
        fixed blocks rest on track circuits), a train behind is held by it, and it is among the `fast_slots` trains
        whose followers have the least authority left."""
        if now_s >= state.fast_until_s or not self.policy.fast_reports:
            return False
        wanting = [st for st in self.trains.values() if now_s < st.fast_until_s]
        if len(wanting) <= self.fast_slots:
            return True
        wanting.sort(key=lambda st: (st.fast_need_m, st.train_id))
        return state in wanting[:self.fast_slots]

    def stop_all(self, now_s: float) -> None:
        """Controller shutdown: command every train that has reported to stop at service rate (speed 0, authority at
        its braking distance, never beyond the one it holds)."""
        for state in self.trains.values():
            if state.report is not None:
                beta_mps2 = state.setup.profile.beta_s_mps2
                self._command(state, None, None, 0.0, beta_mps2, beta_mps2, now_s)

    def _leader_stale(self, state, now_s):
        """True when the data of some other train is older than the limit: the authority must not extend."""
        for other in self.trains.values():
            if other is not state and (other.report_recv_s is None or
                                       now_s - other.report_recv_s > self.params.max_leader_age_s):
                return True
        return False

    def checked_gap_m(self, state, gap_est_m, sigma_m, now_s):
        """The gap (m) the authority may use: the estimated gap, or the train's own measured gap when that is fresh
        and shorter. Raises the "picture disagrees" alarm when they differ by more than 3 sigma of the estimate
        plus 3 sigma of the ranging (`ranging_sigma_m`)."""
        if state.rng_gap is None or now_s - state.rng_gap[0] > self.params.max_leader_age_s:
            state.gap_alarm = False
            return gap_est_m
        measured_m = state.rng_gap[1]
        alarm = abs(gap_est_m - measured_m) > 3.0 * (sigma_m + self.ranging_sigma_m)
        if alarm and not state.gap_alarm:
            state.gap_alarms += 1
            log.warning("train %s: picture disagrees: estimated gap %.3f m, measured %.3f m", state.train_id,
                        gap_est_m, measured_m)
        state.gap_alarm = alarm
        return min(gap_est_m, measured_m) if self.use_measured_gap else gap_est_m

    # --- supervision ------------------------------------------------------------------------------------------------

    def snapshot(self, now_s: float) -> dict:
        """A JSON-ready picture of every train, as the controller sees it."""
        out = {}
        for train_id, st in self.trains.items():
            est = st.estimator.estimate(now_s) if st.report is not None and st.estimator.localized else None
            out[train_id] = {
                "located": est is not None,
                "s_m": None if est is None else round(est.s_m, 4),
                "v_mps": None if est is None else round(est.v_mps, 4),
                "sigma_s_m": None if est is None else round(est.sigma_s_m, 4),
                "limit_s_m": None if st.limit_s is None else round(st.limit_s, 4),
                "leader_data_age_s": None if st.leader_data_t_s is None else round(now_s - st.leader_data_t_s, 3),
                "mode": None if st.report is None else st.report["mode"],
                "faults": [] if st.report is None else list(st.report["flt"]),
                "next_stop": st.next_stop,
                "reports_rejected": st.reports_rejected,
                "gap_measured_m": None if st.rng_gap is None else round(st.rng_gap[1], 4),
                "gap_disagrees": st.gap_alarm,
            }
        return out

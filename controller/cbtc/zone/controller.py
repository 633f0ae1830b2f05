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
from math import isfinite

from cbtc.authority.rules import (
    AuthorityParams,
    checked_gap_m,
    following_reach_m,
    horizon_m,
    scale_trusted,
    within_horizon,
)
from cbtc.authority.values import Situation
from cbtc.errors import ConfigError
from cbtc.firmware import obu
from cbtc.protocol import fast_wire, wire, wire_zc
from cbtc.protocol.records import Command
from cbtc.railway.ips_frame import ips_to_track
from cbtc.railway.physics import braking_distance_m
from cbtc.zone import plausibility
from cbtc.zone.estimators import Estimators
from cbtc.zone.fast_reports import FastReports, fast_report_slots
from cbtc.zone.handover import TrainRecord, export_train, import_train
from cbtc.zone.indexes import ReportAges, TrainOrder
from cbtc.zone.obstacle_watch import ObstacleWatch
from cbtc.zone.refusals import UNKNOWN, RefusalLog, short
from cbtc.zone.stations import STANDING_MMPS, StationStops
from cbtc.zone.supervision import CommandSent, Subscribers, ZoneView, train_view
from cbtc.zone.swept import SweptTrack
from cbtc.zone.tails import TailWatch
from cbtc.zone.train_notes import note_motion_faults, watch_answers
from cbtc.zone.train_state import TrainState

log = logging.getLogger("cbtc.zone")
_SCALE_LOW = wire.ODO_MM_PER_M_MIN / 1000.0    # the odometer metres per true metre a wheel can have: the band
_SCALE_HIGH = wire.ODO_MM_PER_M_MAX / 1000.0   # a command may state (no wheel is off by a factor of two)
_STOP_KEPT_MM = obu.STOP_MADE_MM   # near standstill, a station's stop target moves only when the estimate shifts
#                                   it further than the board holds short of it



class ZoneController:
    def __init__(self, layout, trains, client, now_fn, policy, params: AuthorityParams = None,
                 estimator_factory=None, cycle_s: float = 0.1, zone_id: str = "zc1", seed: int = 0,
                 event_driven: bool = True, report_budget_hz: float = 400.0):
        if not trains:
            raise ValueError("zone controller: no trains configured")
        self.order = TrainOrder(layout.closed)   # the located trains in position order
        self._departing = {}      # train id -> state, trains whose newest authority is a departure
        self._departing_for = {}  # state -> the profiles of the departing trains but it (Situation.departing), kept
        #                           until a train's departure begins or ends
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
        self.stops = StationStops(layout, self._rng)
        if estimator_factory is None:
            from cbtc.estimation.ukf_estimator import UkfEstimator as estimator_factory
        self.refusals = RefusalLog(log)
        self.estimators = Estimators(layout, self.params, self.refusals, estimator_factory)
        self.trains = {}
        self._add_trains(trains)
        self._unanswered = set(self.trains.values())   # states whose newest report does not echo this session
        self.ages = ReportAges(len(self.trains))   # how old each train's newest report is
        if not layout.tags:
            log.warning("layout %s has no RFID tags: no balise can confirm where a train is, so every train placed by "
                        "the IPS alone runs at restricted speed for good; lay tags between the rails and list them in "
                        "the layout (docs/layouts.md)", layout.name)
        self.unknown_reports = 0
        self.invalid_reports = 0
        self.swept = SweptTrack(layout)   # the track vouched for; the rest is occupied (cbtc.zone.swept)
        self.watch = ObstacleWatch(layout, [st.setup.profile for st in self.trains.values()], self.params,
                                   self.refusals)   # what stands on the track and is no train of the zone
        self.obstacles = self.watch.obstacles   # name -> Obstacle (the watch's), read at every authority
        self.key_source = "its keys"   # where the zone's keys come from, named when a board's differ (a file)
        self.cycles = 0
        self.ranging_sigma_m = 0.02   # 1-sigma of a measured gap (cbtc.ranging.transponder.RangingSensor.sigma_m)
        self.use_measured_gap = True  # False: measured gaps only raise the alarm, the authority ignores them
        self.commands = Subscribers("commands")   # each gets a CommandSent after each command is published
        self.reports = Subscribers("reports")     # each gets (train_id, report, recv_s) for each accepted report
        self.views = Subscribers("views")         # each gets the ZoneView of each publish_view()
        self.fast = FastReports(fast_report_slots(report_budget_hz, len(self.trains), self.params),
                                self.params.fast_hold_s)

    def _add_trains(self, setups):
        """A TrainState for each TrainSetup, its fixed distances worked out once; ValueError or LayoutError naming a
        bad id, a train configured twice or a stop the layout does not have."""
        layout = self.layout
        for setup in setups:
            wire.check_train_id(setup.train_id)
            if setup.train_id in self.trains:
                raise ValueError(f"zone controller: train id {setup.train_id!r} configured twice")
            for name in setup.stops:
                layout.station(name)  # raises LayoutError naming the known stations
            state = TrainState(setup, self.estimators.factory(layout, setup.profile), rank=len(self.trains),
                               on_change=self.order.moved.add)
            state.reach_m = following_reach_m(setup.profile)
            state.horizon_m = horizon_m(setup.profile, self.params)
            state.track_m = layout.length_m
            self.trains[setup.train_id] = state

    # --- shell: bus ----------------------------------------------------------------------------------------------

    def start(self):
        """Subscribe to reports and announce the controller (retained)."""
        if not self.swept.spans:
            log.warning("the track is not cleared: no authority reaches track no located train has swept; once only "
                        "this zone's trains stand on it, say so (cbtc zone --clear-track all, or FROM-TO stretches)")
        self.client.subscribe(wire_zc.REPORT_FILTER, self.on_report)
        self.client.publish(wire_zc.topic_zone_status(self.zone_id), b"online", retain=True)

    def declare_position(self, train_id: str, s_m: float, tol_m: float) -> None:
        """An operator declares that `train_id`'s head stands within `tol_m` of track position `s_m`: its first
        placement is confirmed if it agrees (UkfEstimator.declare_position); ConfigError for a train not in the zone."""
        state = self.trains.get(train_id)
        if state is None:
            raise ConfigError(f"declared position: train {train_id!r} is not in this zone; its trains: "
                              f"{', '.join(self.trains)}")
        if not (isfinite(s_m) and isfinite(tol_m) and tol_m >= 0.0):
            raise ConfigError(f"declared position of {train_id}: {s_m} m within {tol_m} m is not a track position "
                              f"and a tolerance >= 0")
        state.estimator.declare_position(s_m, tol_m)

    def clear_track(self, spans=None, by: str = "an operator") -> None:
        """`by` vouches that no vehicle but the zone's trains stands on `spans` ((from_m, to_m) track positions, each
        forward from `from_m`; None: the whole track). Track neither cleared nor swept by a located train is occupied:
        no authority reaches into it."""
        if spans is None:
            self.swept.clear_all()
            log.info("%s cleared the whole track", by)
            return
        for from_m, to_m in spans:
            if not (isfinite(from_m) and isfinite(to_m)):
                raise ConfigError(f"track cleared by {by}: {from_m}-{to_m} m is not a stretch of track")
            self.swept.clear(from_m, to_m if to_m > from_m or not self.layout.closed else to_m + self.layout.length_m)
        log.info("%s cleared %s of the track", by, ", ".join(f"{a:.2f}-{b:.2f} m" for a, b in spans) or "none")

    def on_report(self, topic, payload):
        """Take one report. Whatever it holds, nothing escapes: a refusal is counted and logged at a bounded rate
        (cbtc.zone.refusals), and an exception in one train's handling makes that train be located afresh."""
        recv_s = self.now_fn()
        try:
            train_id = wire.train_id_of(topic)
        except wire.WireError as exc:
            self.invalid_reports += 1
            self.refusals.note(UNKNOWN, "message", exc.reason, recv_s)
            return
        state = self.trains.get(train_id)
        if state is None:
            self.unknown_reports += 1
            self.watch.stranger(train_id, topic, payload, recv_s)
            return
        try:
            self._take_report(state, payload, recv_s)
        except Exception as exc:   # one train's bad data never stops the zone
            self.estimators.train_failed(state, exc, "handling a report", payload, recv_s)

    def _refuse(self, state, klass, reason, recv_s, advice=""):
        state.reports_rejected += 1
        state.last_reject = short(reason)
        self.refusals.note(state.train_id, klass, reason, recv_s, advice)

    def _take_report(self, state, payload, recv_s):
        report = self._decoded(state, payload, recv_s)
        if report is None:
            return
        other_boot = state.boots.boot is not None and report["boot"] != state.boots.boot
        if other_boot and state.boots.second_board(report, recv_s):
            self.watch.other_boot(state, report, recv_s, proven=True)
            return
        previous = state.report if state.report is not None and state.report["boot"] == report["boot"] else None
        reason = state.boots.refusal(report, recv_s)
        if not reason and previous is not None:
            reason = plausibility.time_refusal(report, previous, recv_s, state.report_recv_s)
        if reason:
            self._refuse(state, "report", reason, recv_s)
            if other_boot:
                self.watch.other_boot(state, report, recv_s, proven=False)
            return
        if other_boot:
            self.watch.boot_is_train(state, report["boot"])
        if state.boots.accept(report, recv_s, self.session_id):
            # a new boot: the board restarted; its clock, odometer and sequence began again
            log.warning("train %s restarted (boot %d): locating it afresh", state.train_id, report["boot"])
            state.restart(self.estimators.fresh(state))
            previous = None
        if state.boots.answered:
            self._unanswered.discard(state)
        else:
            self._unanswered.add(state)
        watch_answers(state, recv_s)
        state.clock.observe(report["t_ms"], recv_s)
        report, dropped = plausibility.plausible_parts(report, None if previous is None else previous["odo_mm"])
        if dropped:
            state.measurements_dropped += dropped
            self.refusals.note(state.train_id, "measurement", f"{dropped} IPS fix, tag or range stamped outside "
                               f"its report (t_ms {report['t_ms']})", recv_s)
        note_motion_faults(state, report, previous, recv_s, self.refusals, self.watch)
        report = self.estimators.feed(state, report, previous, payload, recv_s)
        state.odo_moved = previous is None or report["odo_mm"] != previous["odo_mm"]
        state.report = report
        self.ages.took(state, recv_s)
        state.report_recv_s = recv_s
        state.report_t_s = state.clock.to_controller_s(report["t_ms"])
        if state.odo_moved:
            state.still_since_s = state.report_t_s
        state.took_report()
        self.order.moved.add(state)
        if not self.swept.complete and state.estimator.localized:
            self._sweep(state)
        if self.reports:
            self.reports.publish(state.train_id, report, recv_s)
        if report.get("rng") is not None:
            state.rng_gap = (state.clock.to_controller_s(report["rng"][0]), report["rng"][1] / 1000.0)
        if self.event_driven and state.estimator.localized:
            self._answer(state, recv_s)

    def _decoded(self, state, payload, recv_s):
        """The report of `payload`, authenticated and checked; None, counted and said, when it is not one."""
        try:
            report = fast_wire.decode_report(state.setup.key, wire.topic_report(state.train_id), payload)
        except wire.AuthError:
            self.invalid_reports += 1
            self._refuse(state, "wrong key", "its reports fail authentication", recv_s,
                         advice=f"the zone's key is from {self.key_source}: flash the board with it (cbtc flash "
                                f"--keys FILE) or give the zone the board's")
            return None
        except wire.WireError as exc:
            self.invalid_reports += 1
            # a board of another protocol version (authenticated: the key matched) needs this version's firmware
            advice = f"flash the board with this version's firmware (cbtc flash), which speaks version {wire.VERSION}" \
                if " names version " in exc.reason else ""
            self._refuse(state, "invalid report", exc.reason, recv_s, advice=advice)
            return None
        return report

    def _sweep(self, state):
        """Vouch for the track `state`'s train has certainly covered since its previous located report: from the
        front-most place its tail could have been then to the rear-most place its head can be now. Only a confirmed
        train sweeps (an unconfirmed one may be a lasting bias off), and not one whose train line opened (its tail car
        may be gone); one configured longer than it is would vouch for track behind its real tail."""
        est = state.newest_estimate()
        if est is None or not state.estimator.confirmed or "split" in state.report["flt"]:
            state.swept_from_m = None
            return
        k_m = self.params.k_sigma * est.sigma_s_m
        head_low_m = est.s_m - est.behind_m - k_m
        tail_high_m = est.s_m + est.ahead_m + k_m - state.setup.profile.length_m
        from_m = tail_high_m if state.swept_from_m is None else state.swept_from_m
        covered_m = head_low_m - from_m
        if self.layout.closed:   # the short way round: a train covers far less than a loop between two reports
            covered_m = (covered_m + 0.5 * self.layout.length_m) % self.layout.length_m - 0.5 * self.layout.length_m
        if covered_m > 0.0:
            self.swept.clear(from_m, from_m + covered_m)
        state.swept_from_m = tail_high_m

    def _clear_of_unknown(self, state, auth):
        """`auth` cut short of the first track ahead of `state`'s front-most head that is neither cleared nor swept
        (its margin off)."""
        est = state.newest_estimate()
        front_s = self.layout.wrap(est.s_m + est.ahead_m + self.params.k_sigma * est.sigma_s_m)
        distance_m = self.swept.known_ahead_m(front_s) - self.params.margin_m
        if distance_m < auth.distance_m:
            auth = auth.cut_to(max(0.0, distance_m), "track not swept or cleared ahead")
        return auth

    # --- the cycle ---------------------------------------------------------------------------------------------------

    def located(self):
        """Train states with a finite position estimate, ordered by head position along the track (TrainOrder): read
        the list at once, never change it."""
        return self.order.located(self._position_m)

    def _position_m(self, state):
        """The train's head position (m) at its newest report, or None; a filter that fails or turns non-finite
        makes its train be located afresh."""
        try:
            est = state.newest_estimate()
            if est is None or (isfinite(est.s_m) and isfinite(est.sigma_s_m)):
                return None if est is None else est.s_m
            raise ValueError("non-finite estimate")
        except Exception as exc:
            self.estimators.train_failed(state, exc, "estimating its position", b"", self.now_fn())
            return None

    def _all_located(self, located):
        """Every train located, and answering this controller (its reports echo our session): a replayed stream of
        reports never answers, so no authority rests on it."""
        return len(located) == len(self.trains) and not self._unanswered

    def cycle(self, now_s: float):
        """Compute and publish a command for every train that has reported. In event-driven mode a train answered
        since the previous cycle is skipped: the cycle only covers trains whose reports did not arrive."""
        self.cycles += 1
        located = self.located()
        all_located = self._all_located(located)
        leader_of = self.order.leader_of
        for i, state in enumerate(located):
            if self.event_driven and state.answered_s is not None and now_s - state.answered_s < self.cycle_s:
                continue
            self._update(state, leader_of(located, i), all_located, now_s)

    def _update(self, state, leader, all_located, now_s):
        """Command `state`'s train; an exception makes that train be located afresh, and the others go on."""
        try:
            self._authorise(state, leader, all_located, now_s)
        except Exception as exc:
            self.estimators.train_failed(state, exc, "computing its authority", b"", now_s)

    def _authorise(self, state, leader, all_located, now_s):
        stop_m = None
        blind = self.watch.nowhere(state, self.now_fn()) if self.obstacles else None
        braked = None if state.report is None else "reverse" if "reverse" in state.report["flt"] else \
            "split" if "split" in state.report["flt"] else None   # the board brakes it for good
        if all_located and not state.boots.twins and blind is None and braked is None:
            sit = self._situation(state, leader, now_s)
            sit = self.policy.signal(sit)   # fixed block: the wayside sends its speed code through the rails first
            auth = self.watch.clear_of(state, within_horizon(self.policy.authority(sit), state.horizon_m), now_s)
            if not self.swept.complete:
                auth = self._clear_of_unknown(state, auth)
            self._took(state, auth)
            safe_m, v_cap_mps, acc_mps2, dec_mps2 = auth.distance_m, auth.v_cap_mps, auth.acc_mps2, auth.dec_mps2
            stop_m = self.stops.stop_m(state, now_s)
            if leader is not None and safe_m < state.reach_m:
                # this train is held by the one ahead: ask that one for fast reports, for a while
                self.fast.want(leader, safe_m, now_s)
            state.limited_by = auth.reason
            if not state.estimator.confirmed and v_cap_mps > self.params.restricted_mps:
                # placed on one reference: it runs to its next one at restricted speed
                v_cap_mps = self.params.restricted_mps
                state.limited_by = f"restricted speed, until confirmed by a balise ({auth.reason})"
        else:
            safe_m = None
            v_cap_mps = 0.0
            acc_mps2 = dec_mps2 = state.setup.profile.beta_s_mps2
            state.limited_by = f"held: two boards report as {state.train_id}" if state.boots.twins \
                else f"held: {blind}, position unknown" if blind is not None \
                else "held: it ran backwards when driven (motor wired reversed?): fix it, then reboot the board" \
                if braked == "reverse" else "held: its train line opened (a car came off?): recouple, then reboot" \
                if braked == "split" else self._hold_reason()
        self._command(state, safe_m, stop_m, v_cap_mps, acc_mps2, dec_mps2, now_s)
        state.answered_s = now_s

    def on_tail_fix(self, train_id: str, t_s: float, x_mm: int, y_mm: int) -> None:
        """A fix of the beacon on the last car of train `train_id`, IPS frame mm, taken at controller time `t_s` (an
        IPS modem reports every beacon's fixes): it checks the train's configured length (cbtc.zone.tails)."""
        state = self.trains.get(train_id)
        if state is None:
            self.refusals.note(UNKNOWN, "tail fix", f"a tail beacon fix for train {train_id!r}, not in this zone",
                               t_s)
            return
        try:
            self._see_tail(state, t_s, x_mm, y_mm)
        except Exception as exc:   # never stops the zone: the train's tail is not vouched for until heard afresh
            state.tail = None
            self.refusals.note(train_id, "tail fix", f"checking its tail failed: {exc!r}", t_s)

    def _see_tail(self, state, t_s, x_mm, y_mm):
        train_id = state.train_id
        if not state.estimator.localized or state.clock.offset_s is None:
            return
        est = state.estimator.estimate(t_s)
        if est is None:
            return
        x_m, y_m = ips_to_track(x_mm / 1000.0, y_mm / 1000.0, self.layout.ips)
        if state.tail is None:
            state.tail = TailWatch(state.setup.profile.length_m, self.layout.loop_length_m)
        tail = state.tail
        was_longer = tail.longer
        tail.see(t_s, self.layout.project(x_m, y_m), est.s_m)
        if tail.extra_behind_m(est.s_m, t_s) and not was_longer:
            self.refusals.note(train_id, "tail further back", f"its tail beacon puts its tail further back than its "
                               f"configured length ({state.setup.profile.length_m:.2f} m)", t_s,
                               "the train behind keeps back from there; check the train's length in the "
                               "configuration, and whether a car has come off")

    def _hold_reason(self):
        """Why every train is held (no authority): the first train not located, or not answering this zone."""
        for st in self.trains.values():
            if st.report is None:
                return f"held: {st.train_id} not heard"
            if not st.estimator.localized:
                return f"held: {st.train_id} not located"
        if self._unanswered:
            return f"held: {min(self._unanswered, key=lambda st: st.rank).train_id} not answering"
        return "held"

    def _situation(self, state, leader, now_s):
        """The values the policy decides `state`'s authority from, behind `leader` (None: alone)."""
        departing = self._departing_for.get(state) if self._departing else ()
        if departing is None:
            departing = self._departing_for[state] = tuple(
                other.setup.profile for other in sorted(self._departing.values(), key=lambda st: st.rank)
                if other is not state)
        return Situation(self.layout, now_s, self.cycle_s, state.picture(),
                         None if leader is None else leader.picture(), state.rng_gap, self.ranging_sigma_m,
                         self.use_measured_gap, departing, self._spans() if self.policy.needs_spans else ())

    def _spans(self):
        """(train_id, head_s, tail_s) of every train as the track circuits see them: the world's own when the policy
        has them (simulation), otherwise the located trains' estimates widened by k sigma."""
        circuits = getattr(self.policy, "track_circuits", None)
        if circuits is not None:
            return tuple(circuits())
        spans = []
        for st in self.trains.values():
            if st.report is None or not st.estimator.localized:
                continue
            est = st.newest_estimate()
            widen = self.params.k_sigma * est.sigma_s_m
            spans.append((st.train_id, self.layout.wrap(est.s_m + widen + est.ahead_m),
                          self.layout.wrap(est.s_m - st.setup.profile.length_m - widen - st.picture().behind_m)))
        return tuple(spans)

    def _took(self, state, auth):
        """Keep what `state`'s new authority rests on, and raise the "picture disagrees" alarm when it does."""
        state.authority = auth
        state.mode = auth.mode
        if (auth.mode == "departure") != (state.train_id in self._departing):
            if auth.mode == "departure":
                self._departing[state.train_id] = state
            else:
                del self._departing[state.train_id]
            self._departing_for.clear()
        if log.isEnabledFor(logging.DEBUG):
            log.debug("train %s: authority %.3f m (%s), limited by %s", state.train_id, auth.distance_m, auth.mode,
                      auth.reason)
        state.leader_data_t_s = auth.leader_data_t_s
        state.sigma_m = auth.sigma_m
        if auth.gap_est_m is not None:
            self._note_gap(state, auth.gap_alarm, auth.gap_est_m)

    def _note_gap(self, state, alarm, gap_est_m):
        if alarm is None:
            state.gap_alarm = False
            return
        if alarm and not state.gap_alarm:
            state.gap_alarms += 1
            log.warning("train %s: picture disagrees: estimated gap %.3f m, measured %.3f m by its ranging; %s",
                        state.train_id, gap_est_m, state.rng_gap[1],
                        "the authority takes the shorter; check the two trains' IPS and wheels" if self.use_measured_gap
                        else "the authority rests on the estimate alone; the board's guard brakes on the measurement")
        state.gap_alarm = alarm

    def _answer(self, state, now_s):
        """Event-driven: a fresh report is answered at once, and it extends its follower's authority at once too."""
        located = self.located()
        i = self.order.index_of(state)
        if i is None:
            return
        all_located = self._all_located(located)
        self._update(state, self.order.leader_of(located, i), all_located, now_s)
        if all_located and len(located) > 1 and (i > 0 or self.layout.closed):
            self._update(located[i - 1], state, True, now_s)

    def _command(self, state, safe_m, stop_m, v_cap_mps, acc_mps2, dec_mps2, now_s):
        """Publish the command for the end of authority `safe_m` metres ahead (None: none granted: stop) and the
        service stop target `stop_m` metres ahead (None: none); the limit is kept as `limit_s` on the track for
        supervision."""
        report = state.report
        # a low bound of the encoder's scale (odometer m per true m): a wheel that reads short must not carry the
        # train past its limit; the board's braking curves use it too (odo_mm_per_m). Outside the band a wheel can
        # have, the mapping into odometer units is not trusted: no authority beyond braking, the train stops
        scale_low = state.odometer_per_m_low(self.params.k_sigma)
        if not scale_trusted(scale_low, _SCALE_LOW, _SCALE_HIGH):
            if safe_m is not None:
                self.refusals.note(state.train_id, "encoder scale", f"learnt {scale_low:.3f} odometer m per m, outside "
                                   f"[{_SCALE_LOW}, {_SCALE_HIGH}]: no authority until it is learnt again", now_s)
            safe_m, stop_m, v_cap_mps, dec_mps2 = None, None, 0.0, state.setup.profile.beta_s_mps2
            scale_low = _SCALE_LOW
            state.limited_by = "held: encoder scale unknown"
        eoa_mm = self._end_of_authority_mm(state, safe_m, scale_low, dec_mps2, now_s)
        # a stop target is service, not safety: the best estimate of the scale, and never beyond the end of authority
        stop_mm = eoa_mm if stop_m is None else \
            min(eoa_mm, report["odo_mm"] + int(round(stop_m * min(_SCALE_HIGH, max(
                _SCALE_LOW, state.odometer_per_m_low(0.0))) * 1000.0)))
        held = state.command
        if stop_m is not None and held is not None and report["v_mmps"] < 2 * STANDING_MMPS:
            if (held.boot == report["boot"] and held.stop_mm < held.eoa_mm and held.stop_mm <= eoa_mm
                    and abs(stop_mm - held.stop_mm) <= _STOP_KEPT_MM):
                # braking onto the mark: a target a mm or two off the one the board holds is the estimate's noise,
                # and moving it would start a train the board has just stopped there (it holds that near it)
                stop_mm = held.stop_mm
        est = state.newest_estimate()
        if est is None:
            state.limit_s = None
        else:
            limit_mm = eoa_mm - report["odo_mm"] if safe_m is None else safe_m * 1000.0
            state.limit_s = self.layout.wrap(est.s_m + limit_mm / 1000.0)
        # fast reports rest on train reports (moving block; fixed blocks rest on track circuits)
        fast = self.policy.fast_reports and self.fast.granted(state, now_s)
        rpt_ms = self.params.fast_report_ms if fast or self.stops.leaving_soon(state, now_s) else 0
        # the command's fields after boot and seq, in the table's order (Command: sid, rseq, v_mmps, eoa_mm, ttl_ms,
        # acc, dec, stop_mm, rpt_ms, odo_mm_per_m), as a tuple: a zone builds one for every answer it makes
        rest = (self.session_id, report["seq"], int(max(0.0, v_cap_mps) * 1000), eoa_mm, int(self.params.ttl_s * 1000),
                max(1, int(acc_mps2 * 1000)), max(1, int(dec_mps2 * 1000)), stop_mm, rpt_ms,
                max(wire.ODO_MM_PER_M_MIN, min(wire.ODO_MM_PER_M_MAX, int(scale_low * 1000.0))))   # floored
        if held is not None and held[2:] == rest and held.boot == report["boot"]:
            # the board holds this very command (same report, so the same expiry): sending it again changes nothing
            return
        command = Command(report["boot"], wire.wrap_add(state.cmd_seq, 1), *rest)
        state.command = command
        state.cmd_seq = command.seq
        payload = fast_wire.encode_command(state.setup.key, state.train_id, *command)
        self.client.publish(wire.topic_command(state.train_id), payload)
        if self.commands:
            self.commands.publish(CommandSent(state.train_id, now_s, command, state.limited_by, state.leader_data_t_s,
                                              state.sigma_m, state.estimator.confirmed))

    def _end_of_authority_mm(self, state, safe_m, scale_low, dec_mps2, now_s):
        """The end of authority, in the train's odometer mm, for `safe_m` metres of track ahead (None: stop) at the
        encoder's low scale `scale_low`; kept as the one the train holds (never extended from stale data)."""
        report = state.report
        state.safe_m = safe_m
        if safe_m is None:
            # no picture of every train: stop now at service rate; the authority never extends. Its end is the
            # braking distance from the highest speed the train can have reached since its report (the report's
            # speed lags half a speed window; the train may have accelerated since): a standing train is held where
            # it stands, not granted room it may not have. The stop is the speed cap 0
            profile = state.setup.profile
            lag_s = max(0.0, now_s - state.report_t_s) + obu.DEFAULTS["speed_window_ms"] / 1000.0 + profile.reaction_s
            v_mps = min(profile.v_noload_mps, report["v_mmps"] / 1000.0 + profile.accel_max_mps2 * lag_s)
            brake_m = v_mps * profile.reaction_s + braking_distance_m(v_mps, dec_mps2)
            eoa_mm = report["odo_mm"] + int(brake_m * 1000.0)
        else:
            # metres along the track into odometer mm at the lowest scale the wheel reads, and no further than a wheel
            # that began to slide by slide_share now would carry the train into the margin beyond (at a long
            # authority the slide's share is more than the margin)
            reach_m = min(safe_m * scale_low, (1.0 - self.params.slide_share) * (safe_m + self.params.margin_m))
            eoa_mm = report["odo_mm"] + int(reach_m * 1000.0)
        if state.eoa_mm is not None and (safe_m is None or self._leader_stale(state, now_s)):
            if safe_m is not None and eoa_mm > state.eoa_mm:
                state.limited_by = "not extended: stale data"
            eoa_mm = min(eoa_mm, state.eoa_mm)
        state.eoa_mm = eoa_mm
        return eoa_mm

    def stop_all(self, now_s: float) -> None:
        """Controller shutdown: command every train that has reported to stop at service rate (speed 0, authority at
        its braking distance, never beyond the one it holds)."""
        for state in self.trains.values():
            if state.report is not None:
                beta_mps2 = state.setup.profile.beta_s_mps2
                self._command(state, None, None, 0.0, beta_mps2, beta_mps2, now_s)

    def _leader_stale(self, state, now_s):
        """True when the data of some other train is older than the limit: the authority must not extend."""
        return self.ages.other_stale(state, now_s, self.params.max_leader_age_s)

    def checked_gap_m(self, state, gap_est_m, sigma_m, now_s):
        """The gap (m) the authority may use from the estimated one and `state`'s own measured gap
        (cbtc.authority.rules.checked_gap_m), raising the "picture disagrees" alarm when they differ."""
        gap_m, alarm = checked_gap_m(gap_est_m, sigma_m, state.rng_gap, now_s, self.params, self.ranging_sigma_m,
                                     self.use_measured_gap)
        self._note_gap(state, alarm, gap_est_m)
        return gap_m

    # --- supervision ------------------------------------------------------------------------------------------------

    def view(self, now_s: float) -> ZoneView:
        """The frozen picture of the zone and every train at `now_s` (the supervision read-model)."""
        return ZoneView(self.zone_id, self.session_id, now_s, tuple(train_view(st, now_s, self.params.max_leader_age_s)
                                                                    for st in self.trains.values()),
                        self.cycles, self.unknown_reports, self.invalid_reports,
                        tuple(sorted(self.refusals.counts.items())))

    def publish_view(self, now_s: float) -> ZoneView:
        """The view at `now_s`, handed to every subscriber of `views`."""
        view = self.view(now_s)
        self.views.publish(view)
        return view

    def snapshot(self, now_s: float) -> dict:
        """{train id: its JSON-ready status row} at `now_s` (TrainView.status)."""
        return self.view(now_s).status()

    def authority_m(self, train_id: str):
        """How far `train_id`'s safety limit allowed at its newest command (m; None: held): what a simulation's
        monitor reads every sample, without the cost of a view."""
        return self.trains[train_id].safe_m

    def estimate_at(self, train_id: str, now_s: float, position_only: bool = False):
        """`train_id`'s estimate at `now_s` (an Estimate; its head position alone, cheaper, when `position_only`), or
        None while it has none: what a simulation's monitor compares with truth every sample."""
        state = self.trains[train_id]
        if state.report is None or not state.estimator.localized:
            return None
        return state.estimator.position_m(now_s) if position_only else state.estimator.estimate(now_s)

    def export_train(self, train_id: str, now_s: float) -> TrainRecord:
        """What another zone needs to take `train_id` over at `now_s`, as a value (cbtc.zone.handover)."""
        return export_train(self._known(train_id), now_s)

    def import_train(self, record: TrainRecord, now_s: float) -> None:
        """Take over the train of `record` (exported by another zone, or by this zone before a restart) at `now_s`."""
        import_train(self._known(record.train_id), record, now_s, Command)

    def _known(self, train_id):
        state = self.trains.get(train_id)
        if state is None:
            raise ConfigError(f"train {train_id!r} is not in this zone; its trains: {', '.join(self.trains)}")
        return state

    def retune(self, train_id: str, profile) -> None:
        """Take `profile` for `train_id` from now (an operator's correction, or an experiment's wrong one) and
        start its estimate again from nothing."""
        state = self.trains[train_id]
        state.setup.profile = profile
        state.relocate(type(state.estimator)(self.layout, profile))

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

from cbtc.authority.rules import AuthorityParams, within_horizon
from cbtc.authority.values import Situation
from cbtc.errors import ConfigError
from cbtc.protocol import wire, wire_zc
from cbtc.protocol.records import Command
from cbtc.zone import plausibility
from cbtc.zone.commanding import CommandWriter
from cbtc.zone.decoding import decoded_report
from cbtc.zone.estimators import Estimators
from cbtc.zone.fast_reports import FastReports, fast_report_slots
from cbtc.zone.handover import TrainRecord, export_train, import_train
from cbtc.zone.indexes import ReportAges, TrainOrder
from cbtc.zone.network_routes import network_routes
from cbtc.zone.obstacle_watch import ObstacleWatch
from cbtc.zone.refusals import UNKNOWN, RefusalLog, short
from cbtc.zone.situations import Departures, hold_reason, own_hold, track_spans
from cbtc.zone.stations import StationStops
from cbtc.zone.supervision import Subscribers, ZoneView, train_view
from cbtc.zone.swept import SweptTrack
from cbtc.zone.tails import take_tail_fix
from cbtc.zone.train_notes import note_gap, note_motion_faults, watch_answers
from cbtc.zone.train_state import train_states

log = logging.getLogger("cbtc.zone")


class ZoneController:
    def __init__(self, layout, trains, client, now_fn, policy, params: AuthorityParams = None,
                 estimator_factory=None, cycle_s: float = 0.1, zone_id: str = "zc1", seed: int = 0,
                 event_driven: bool = True, report_budget_hz: float = 400.0):
        if not trains:
            raise ValueError("zone controller: no trains configured")
        self.order = TrainOrder(getattr(layout, "closed", False))   # the located trains in position order
        self.departures = Departures()   # the trains departing, for each train's Situation
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
        self.stops = StationStops(self._rng)
        if estimator_factory is None:
            from cbtc.estimation.ukf_estimator import UkfEstimator as estimator_factory
        self.refusals = RefusalLog(log)
        self.estimators = Estimators(layout, self.params, self.refusals, estimator_factory)
        self.trains = train_states(trains, layout, self.params, estimator_factory, self.order.moved.add)
        self._unanswered = set(self.trains.values())   # states whose newest report does not echo this session
        self.ages = ReportAges(len(self.trains))   # how old each train's newest report is
        if not layout.tags:
            log.warning("layout %s has no RFID tags: no balise can confirm where a train is, so every train placed by "
                        "the IPS alone runs at restricted speed for good; lay tags between the rails and list them in "
                        "the layout (docs/layouts.md)", layout.name)
        self.unknown_reports = 0
        self.invalid_reports = 0
        self.swept = SweptTrack(layout)   # the track vouched for; the rest is occupied (cbtc.zone.swept)
        self.network = network_routes(layout, self.trains, self.params, policy, self.estimators)   # else None
        self.watch = ObstacleWatch(None if self.network else layout,
                                   [st.setup.profile for st in self.trains.values()], self.params,
                                   self.refusals)   # what stands on the track and is no train of the zone
        self.obstacles = self.watch.obstacles   # name -> Obstacle (the watch's), read at every authority
        self.key_source = "its keys"   # where the zone's keys come from, named when a board's differ (a file)
        self.cycles = 0
        self.ranging_sigma_m = 0.02   # 1-sigma of a measured gap (cbtc.ranging.transponder.RangingSensor.sigma_m)
        self.use_measured_gap = True  # False: measured gaps only raise the alarm, the authority ignores them
        self.commands = Subscribers("commands")   # each gets a CommandSent after each command is published
        self.reports = Subscribers("reports")     # each gets (train_id, report, recv_s) for each accepted report
        self.views = Subscribers("views")         # each gets the ZoneView of each publish_view()
        self.writer = CommandWriter(layout, self.params, client, self.session_id, self.refusals, self.ages,
                                    self.commands)
        self.fast = FastReports(fast_report_slots(report_budget_hz, len(self.trains), self.params),
                                self.params.fast_hold_s)

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
        """`by` vouches that no vehicle but the zone's trains stands on `spans` ((from_m, to_m) track positions; None:
        the whole track; SweptTrack.vouch)."""
        self.swept.vouch(spans, by)

    def on_tail_fix(self, train_id: str, t_s: float, x_mm: int, y_mm: int) -> None:
        """A fix of the beacon on the last car of train `train_id`, IPS frame mm, taken at controller time `t_s`: it
        checks the train's configured length (cbtc.zone.tails)."""
        take_tail_fix(self.trains, self.layout, self.refusals, train_id, t_s, x_mm, y_mm)

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
        if not self.swept.complete and state.estimator.localized and self.network is None:
            self.swept.sweep(state, self.params.k_sigma)
        if self.reports:
            self.reports.publish(state.train_id, report, recv_s)
        if report.get("rng") is not None:
            state.rng_gap = (state.clock.to_controller_s(report["rng"][0]), report["rng"][1] / 1000.0)
        if self.event_driven and state.estimator.localized:
            self._answer(state, recv_s)

    def _decoded(self, state, payload, recv_s):
        """The report of `payload`, authenticated and checked; None, counted and said, when it is not one."""
        report, refusal = decoded_report(state, payload, self.key_source)
        if report is None:
            self._refuse(state, refusal[0], refusal[1], recv_s, refusal[2])
            self.invalid_reports += 1
        return report

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
        if self.network is not None:
            self.network.refresh(located, now_s)
        for i, state in enumerate(located):   # each behind the train ahead (on a network: ahead on its route)
            if self.event_driven and state.answered_s is not None and now_s - state.answered_s < self.cycle_s:
                continue
            self._update(state, self.order.leader_of(located, i) if self.network is None else
                         self.network.leader(state, located), all_located, now_s)

    def _update(self, state, leader, all_located, now_s):
        """Command `state`'s train; an exception makes that train be located afresh, and the others go on."""
        try:
            self._authorise(state, leader, all_located, now_s)
        except Exception as exc:
            self.estimators.train_failed(state, exc, "computing its authority", b"", now_s)

    def _authorise(self, state, leader, all_located, now_s):
        stop_m = None
        blind = self.watch.nowhere(state, self.now_fn()) if self.obstacles else None
        why = own_hold(state, blind, self.network is not None and not self.swept.complete)
        if why is None and not all_located:
            why = hold_reason(self.trains, self._unanswered)
        if why is None:
            sit = self._situation(state, leader, now_s)
            sit = self.policy.signal(sit)   # fixed block: the wayside sends its speed code through the rails first
            auth = self.watch.clear_of(state, within_horizon(self.policy.authority(sit), state.horizon_m), now_s)
            if self.network is not None:
                auth = self.network.clear_of(state, auth, now_s, leader)
            elif not self.swept.complete:
                auth = self.swept.clear_of(state, auth, self.params.k_sigma, self.params.margin_m)
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
            state.limited_by = why
        self._command(state, safe_m, stop_m, v_cap_mps, acc_mps2, dec_mps2, now_s)
        state.answered_s = now_s

    def _situation(self, state, leader, now_s):
        """The values the policy decides `state`'s authority from, behind `leader` (None: alone)."""
        spans = () if not self.policy.needs_spans else self.network.frame_spans(state) if self.network else \
            track_spans(self.policy, self.trains, self.layout, self.params.k_sigma)
        ahead = None if leader is None else leader.picture() if self.network is None else \
            self.network.picture_for(leader, state)   # on a network, in `state`'s frame
        return Situation(state.frame, now_s, self.cycle_s, state.picture(), ahead, state.rng_gap,
                         self.ranging_sigma_m, self.use_measured_gap, self.departures.of_others(state), spans)

    def _took(self, state, auth):
        """Keep what `state`'s new authority rests on, and raise the "picture disagrees" alarm when it does."""
        state.authority = auth
        state.mode = auth.mode
        self.departures.took(state, auth.mode)
        if log.isEnabledFor(logging.DEBUG):
            log.debug("train %s: authority %.3f m (%s), limited by %s", state.train_id, auth.distance_m, auth.mode,
                      auth.reason)
        state.leader_data_t_s = auth.leader_data_t_s
        state.sigma_m = auth.sigma_m
        if auth.gap_est_m is not None:
            note_gap(state, auth.gap_alarm, auth.gap_est_m, self.use_measured_gap)

    def _answer(self, state, now_s):
        """Event-driven: a fresh report is answered at once, and it extends its follower's authority at once too."""
        located = self.located()
        i = self.order.index_of(state)
        if i is None:
            return
        all_located, net = self._all_located(located), self.network
        if net is not None:
            net.refresh(located, now_s)
        self._update(state, self.order.leader_of(located, i) if net is None else net.leader(state, located),
                     all_located, now_s)
        behind = () if not all_located else net.followers(state, located) if net is not None else \
            (located[i - 1],) if len(located) > 1 and (i > 0 or self.layout.closed) else ()
        for other in behind:
            self._update(other, state, True, now_s)

    def _command(self, state, safe_m, stop_m, v_cap_mps, acc_mps2, dec_mps2, now_s):
        """Publish the command for the end of authority `safe_m` metres ahead (None: none granted: stop) and the
        service stop target `stop_m` metres ahead (None: none), fast reports asked when they are granted
        (CommandWriter.send)."""
        # fast reports rest on train reports (moving block; fixed blocks rest on track circuits)
        fast = self.policy.fast_reports and self.fast.granted(state, now_s)
        rpt_ms = self.params.fast_report_ms if fast or self.stops.leaving_soon(state, now_s) else 0
        self.writer.send(state, safe_m, stop_m, v_cap_mps, acc_mps2, dec_mps2, rpt_ms, now_s)

    def stop_all(self, now_s: float) -> None:
        """Controller shutdown: every train that has reported is commanded to stop at service rate, in its authority."""
        for state in self.trains.values():
            if state.report is not None:
                beta_mps2 = state.setup.profile.beta_s_mps2
                self._command(state, None, None, 0.0, beta_mps2, beta_mps2, now_s)

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
        return export_train(self.state_of(train_id), now_s)

    def import_train(self, record: TrainRecord, now_s: float) -> None:
        """Take over the train of `record` (exported by another zone, or by this zone before a restart) at `now_s`."""
        import_train(self.state_of(record.train_id), record, now_s, Command)

    def state_of(self, train_id: str):
        """The zone's own state of `train_id` (a TrainState): for white-box tests and a simulation's fault effects."""
        state = self.trains.get(train_id)
        if state is None:
            raise ConfigError(f"train {train_id!r} is not in this zone; its trains: {', '.join(self.trains)}")
        return state

    def retune(self, train_id: str, profile) -> None:
        """Take `profile` for `train_id` from now (an operator's correction, or an experiment's wrong one) and
        start its estimate again from nothing."""
        state = self.state_of(train_id)
        state.setup.profile = profile
        state.relocate(type(state.estimator)(state.sensor_frame, profile))

"""Commands out: a train's authority, in metres of track, turned into the sealed command its board obeys, in its
own odometer's millimetres.

The end of authority is mapped at the lowest scale the train's wheel can read (a wheel that reads short must not
carry it past its limit) and never extended from stale data; the stop target is service, not safety, and never lies
beyond the end of authority. A command the board already holds is not sent again.
"""

from cbtc.authority.rules import scale_trusted
from cbtc.firmware import obu
from cbtc.protocol import fast_wire, wire
from cbtc.protocol.records import Command
from cbtc.railway.physics import braking_distance_m
from cbtc.zone.stations import STANDING_MMPS
from cbtc.zone.supervision import CommandSent

SCALE_LOW = wire.ODO_MM_PER_M_MIN / 1000.0    # the odometer metres per true metre a wheel can have: the band
SCALE_HIGH = wire.ODO_MM_PER_M_MAX / 1000.0   # a command may state (no wheel is off by a factor of two)
STOP_KEPT_MM = obu.STOP_MADE_MM   # near standstill, a station's stop target moves only when the estimate shifts
#                                   it further than the board holds short of it


class CommandWriter:
    def __init__(self, layout, params, client, session_id, refusals, ages, commands):
        self.layout = layout
        self.params = params
        self.client = client           # the bus the commands are published on
        self.session_id = session_id   # this zone's session, echoed by the reports that answer it
        self.refusals = refusals
        self.ages = ages               # the age of every train's newest report (ReportAges)
        self.commands = commands       # subscribers told of each command published

    def send(self, state, safe_m, stop_m, v_cap_mps, acc_mps2, dec_mps2, rpt_ms, now_s):
        """Publish the command for the end of authority `safe_m` metres ahead (None: none granted: stop) and the
        service stop target `stop_m` metres ahead (None: none), asking for reports every `rpt_ms` (0: the board's
        own rate); the limit is kept as `limit_s` on the track for supervision."""
        report = state.report
        # a low bound of the encoder's scale (odometer m per true m): a wheel that reads short must not carry the
        # train past its limit; the board's braking curves use it too (odo_mm_per_m). Outside the band a wheel can
        # have, the mapping into odometer units is not trusted: no authority beyond braking, the train stops
        scale_low = state.odometer_per_m_low(self.params.k_sigma)
        if not scale_trusted(scale_low, SCALE_LOW, SCALE_HIGH):
            if safe_m is not None:
                self.refusals.note(state.train_id, "encoder scale", f"learnt {scale_low:.3f} odometer m per m, outside "
                                   f"[{SCALE_LOW}, {SCALE_HIGH}]: no authority until it is learnt again", now_s)
            safe_m, stop_m, v_cap_mps, dec_mps2 = None, None, 0.0, state.setup.profile.beta_s_mps2
            scale_low = SCALE_LOW
            state.limited_by = "held: encoder scale unknown"
        eoa_mm = self._end_of_authority_mm(state, safe_m, scale_low, dec_mps2, now_s)
        # a stop target is service, not safety: the best estimate of the scale, and never beyond the end of authority
        stop_mm = eoa_mm if stop_m is None else \
            min(eoa_mm, report["odo_mm"] + int(round(stop_m * min(SCALE_HIGH, max(
                SCALE_LOW, state.odometer_per_m_low(0.0))) * 1000.0)))
        held = state.command
        if stop_m is not None and held is not None and report["v_mmps"] < 2 * STANDING_MMPS:
            if (held.boot == report["boot"] and held.stop_mm < held.eoa_mm and held.stop_mm <= eoa_mm
                    and abs(stop_mm - held.stop_mm) <= STOP_KEPT_MM):
                # braking onto the mark: a target a mm or two off the one the board holds is the estimate's noise,
                # and moving it would start a train the board has just stopped there (it holds that near it)
                stop_mm = held.stop_mm
        est = state.newest_estimate()
        if est is None:
            state.limit_s = None
        else:
            limit_mm = eoa_mm - report["odo_mm"] if safe_m is None else safe_m * 1000.0
            state.limit_s = state.frame.wrap(est.s_m + limit_mm / 1000.0)
        # the command's fields after boot and seq, in the table's order (Command: sid, rseq, v_mmps, eoa_mm, ttl_ms,
        # acc, dec, stop_mm, rpt_ms, odo_mm_per_m, dir), as a tuple: a zone builds one for every answer it makes
        rest = (self.session_id, report["seq"], int(max(0.0, v_cap_mps) * 1000), eoa_mm, int(self.params.ttl_s * 1000),
                max(1, int(acc_mps2 * 1000)), max(1, int(dec_mps2 * 1000)), stop_mm, rpt_ms,
                max(wire.ODO_MM_PER_M_MIN, min(wire.ODO_MM_PER_M_MAX, int(scale_low * 1000.0))),   # floored
                state.travel_dir)
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
        if state.eoa_mm is not None and (
                safe_m is None or self.ages.other_stale(state, now_s, self.params.max_leader_age_s)):
            if safe_m is not None and eoa_mm > state.eoa_mm:
                state.limited_by = "not extended: stale data"
            eoa_mm = min(eoa_mm, state.eoa_mm)
        state.eoa_mm = eoa_mm
        return eoa_mm

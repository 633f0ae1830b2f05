"""The OnboardUnit: the train's loop logic, written once for the real board and for every virtual train.

Drivers (encoder, ips, rfid, motor, an optional ranging driver) and `publish(topic, payload)` are injected; the shell
calls `step(now_ms)` every few ms and `on_message(topic, payload, now_ms)` for each MQTT message, `now_ms` being a
monotonic board time. Nothing here reads a clock or a socket. A step samples the sensors, supervises the end of
authority (a value of the train's own odometer, so it holds between commands), rides a speed reference under the
service braking curve to it and to the stop target, runs the speed PI loop and reports. An expired command means a
target speed of zero; a speed over the braking curve by a margin trips the motor brake, and so does a fresh measured
gap to the train ahead shorter than the emergency braking distance (the collision guard, fault "guard").

A board loads this module's bytecode onto its heap, where every function costs bytes, so the unit's long methods
stay whole. Split by what they do, each costs more of the 32-bit loop heap (tests/test_heap32.py, 34624 B whole):
`_sample` into reading, speed and encoder checks 224 B, `_control` into protection, reference and drive 256 B, the
config check out of `__init__` 48 B; the module split (its defaults and their check alone, as a module of their own)
864 B.
"""

from math import sqrt

try:
    from . import wire  # the controller imports the firmware as the package cbtc.firmware
except ImportError:
    import wire  # a board holds the firmware's modules at the top level

# board-time arithmetic, named once: the loop compares times every pass (a module's attribute is looked up per use)
wrap_add, wrap_diff = wire.wrap_add, wire.wrap_diff

try:
    from micropython import const
except ImportError:  # CPython
    def const(value):
        return value

DEFAULTS = {
    "counts_per_m": 1000,     # encoder counts per metre of travel (calibrate: cbtc calibrate encoder)
    "report_ms": 50,          # report period (ms) unless a valid command asks for another (`rpt_ms`)
    "v_max_mmps": 600,        # line speed ceiling of this train (mm/s)
    "v_noload_mmps": 750,     # speed at 100 % duty, for the PI feed-forward (mm/s)
    "acc_mmps2": 600,         # acceleration when a command does not say (mm/s^2)
    "dec_mmps2": 800,         # service deceleration: the braking curve to the end of authority (mm/s^2)
    "emergency_dec_mmps2": 1400,  # what the motor brake delivers: the trip curve (mm/s^2)
    "kp": 0.1,                # PI proportional gain (% duty per mm/s; 0.05 rode 40 mm/s over a rising curve)
    "ki": 0.25,               # PI integral gain (% duty per mm of accumulated error)
    "reaction_ms": 60,        # time from a speed excess to braking effect, counted into the braking curve (ms)
    "motor_tau_ms": 250,      # motor + inertia time constant, for the acceleration feed-forward (ms)
    "speed_window_ms": 20,    # encoder speed: counts between edges at least this far apart, over their time (ms)
    "trip_margin_mmps": 40,   # speed above the emergency braking curve that trips the motor brake (mm/s)
    "max_data_age_ms": 1000,  # a command based on an older report of ours is stale and refused (ms)
    "ips_silent_ms": 2000,    # no IPS fix for this long raises the ips_silent fault (ms)
    "stall_ms": 1500,         # duty applied but no encoder counts for this long raises enc_stall (ms)
    "stop_window_mm": 5,      # the service curve ends this short of the end of authority (mm per true m of odometer
                              # scale): at least reaction^2 dec emergency / (2 (emergency - dec)), 3.4 mm here
    "enc_slack_mm": 60,       # travel the speed reference may ask for without an encoder count (mm)
    "drive_margin_pct": 20,   # duty allowed above the feed-forward of the speed reference (%)
    "guard_margin_mm": 100,   # collision guard: measured gap kept beyond the emergency braking distance (mm)
    "guard_fresh_ms": 300,    # collision guard: a measured gap older than this is not acted on (ms)
    "max_authority_mm": 20000,  # an end of authority further ahead of the odometer than this is refused: no line
                              # of this train is longer (set it to the layout's length; cbtc sim does) (mm)
}

_HISTORY = const(12)     # reports remembered for matching commands to the report they are based on
_SPEED_RING = const(8)   # encoder snapshots kept for the speed estimate
_US_WRAP = const(262144000)   # edge times (us) wrap with the board's ms at 2^18: small ints; spans are < 1 s
_LEFT_SIDS = const(4)    # sessions remembered as left: a replayed command of any of them is refused
_CREEP_MMPS = const(30)  # below this the service curve is zero: the train stops and holds (mm/s)
STOP_MADE_MM = const(3)  # braked this near a station's mark, the stop is made: held there, not driven up to it (mm)
_ENC_COUNTS = const(3)   # counts the train surely travelled without one coming: the encoder has failed
_ADHESION_MMPS2 = const(3000)  # no train stops faster than this (wheel adhesion): counts must keep coming (mm/s^2)
_ENC_HOLD_MS = const(2000)     # a failed encoder holds the train braked this long after its last sign (ms)
_SAT_MS = const(300)     # drive at its ceiling this long with the train slower than the reference: encoder failed
_SLOW_MMPS = const(50)   # what "slower" means there (mm/s)
_SPAN_MAX_MS = const(65535)   # the longest time a tag read's span may state (wire_zc.SPAN_MAX_MS)
_BACK_MM = const(20)     # a two-channel encoder seeing the train this far behind the furthest it reached: it rolls
                         # back (undriven: held by driving forward) or runs backwards (driven: braked for good) (mm)
_JUMP_MM = const(50)     # a signed count this far back in one pass (2.5 m/s at 20 ms) is a glitch, not a roll (mm)
_STAND_MS = const(500)   # a train takes a change of direction once its odometer has been still this long (ms)
_HOLD_DONE_MM = const(5)  # a hold drives the train back to within this of the furthest it reached, then brakes (mm)


class OnboardUnit:
    # Fields that keep these values until something rare happens (a rejected command, a failed sensor, a guard trip)
    # live on the class, so an instance pays for them only once it changes them; all are immutable.
    ranging = None
    rejected = 0
    last_reject = ""
    sensor_errors = 0
    last_sensor_error = ""
    gap_mm = None            # newest measured gap to the train ahead (mm) and its board time (ms)
    gap_t_ms = 0
    _rng_report = None
    guard_on = False
    guard_trips = 0
    trips = 0                # times the speed crossed the trip curve (emergency brake)
    enc_fail_ms = None       # board time of the newest sign of a failed encoder (None: healthy)
    enc_fails = 0            # times the encoder was found failed
    _v_edge = 0              # measured speed at the newest count (mm/s)
    _ref_mm = 0.0            # travel the speed reference asked for since the newest count (mm)
    _sat_ms = 0              # how long the drive has been at its ceiling with the train slower than asked (ms)
    _undriven = False        # some pass since the last report braked or drove at zero duty
    _left_sids = ()          # controller sessions this unit has left (newest last)
    _peak_mm = 0             # furthest odometer reached: trains run forward only, so travel back is a roll or a fault
    holding = False          # roll-away protection: driving the train forward to where it stood
    holds = 0                # times a roll back was held
    _held = False            # some pass since the last report held a roll back
    way = 1                  # the way of travel the newest command set (its `dir`): 1 forward, -1 backwards
    reverse = False          # the train ran backwards while driven (a motor wired reversed): braked until a reboot
    integrity = None         # the train line's pin where a loop is fitted: it reads 1 once the loop is open
    split = False            # the train line opened (a car came off): braked until a reboot
    _codec = wire            # decodes commands and encodes reports: wire, or the controller's codec of the same bytes

    def __init__(self, train_id, key, boot_id, encoder, ips, rfid, motor, publish, config=None, ranging=None,
                 codec=None):
        self.train_id = wire.check_train_id(train_id)
        self.boot_id = boot_id   # random at each boot (assemble.new_boot_id); every command must name it
        self._key = key
        self.encoder = encoder
        self.ips = ips
        self.rfid = rfid
        self.motor = motor
        if ranging is not None:
            self.ranging = ranging
        if codec is not None:
            self._codec = codec
        self._publish = publish
        cfg = DEFAULTS   # read-only here: shared as it is when nothing is overridden (a board's heap is small)
        if config:
            cfg = dict(DEFAULTS)
            for name in config:
                if name not in DEFAULTS:
                    raise ValueError("unknown config key %r; known: %s"
                                     % (name, ", ".join(sorted(DEFAULTS))))
                cfg[name] = config[name]
        cpm = cfg["counts_per_m"]
        if not isinstance(cpm, int):
            if not isinstance(cpm, float) or cpm != int(cpm):
                raise ValueError("counts_per_m must be whole, not %r (cbtc calibrate encoder)"
                                 % (cpm,))
            cfg = dict(cfg)
            cfg["counts_per_m"] = int(cpm)
        r_s = cfg["reaction_ms"] / 1000
        dec = cfg["dec_mmps2"]
        emergency = cfg["emergency_dec_mmps2"]
        if emergency <= dec or cfg["stop_window_mm"] < r_s * r_s * dec * emergency / (2 * (emergency - dec)):
            raise ValueError("curves cross: raise emergency_dec_mmps2 over dec_mmps2, or stop_window_mm")
        self.cfg = cfg
        self._report_topic = wire.topic_report(train_id)
        self._cmd_topic = wire.topic_command(train_id)
        # odometry
        self.odo_mm = 0
        self.v_mmps = 0
        self._ring_t = [0] * _SPEED_RING   # edge times (us, wrapping at _US_WRAP)
        self._ring_n = [0] * _SPEED_RING   # and their counts
        self._ring_i = 0
        self._last_move_ms = 0
        # authority
        self.sid = -1
        self.cseq = -1
        self.cmd = None
        self.cmd_expiry_ms = 0
        self.eoa_mm = 0               # no authority at start: the end of authority is where the train stands
        self._rejected_since_report = False
        # control
        self.mode = "idle"
        self.v_ref_mmps = 0.0
        self._integral = 0.0
        self._a_lp = 0.0
        self.duty_pct = 0
        # passes since the last report << 16 plus their duties' sum (%), for their mean (the sum fits 16 bits for
        # report periods up to 13 s of 20 ms passes, where a command's 0.8 s time to live has long run out)
        self._duty_acc = 0
        self._last_step_ms = None
        # reporting
        self.seq = 0
        self._report_slot_ms = 0      # board time the newest report was due
        self._sent_seq = [-1] * _HISTORY
        self._sent_t = [0] * _HISTORY
        self._ips_fix = None
        self._tags = []
        self._rfid_ms = None          # board time of the reader's previous poll that answered (None: none yet)
        self.faults = []
        self.link_ok = True
        # a train braked to a standstill that the one-channel encoder sees move rolls (back on a slope, pushed, or
        # sliding on): the direction is unknown, so the report says so (`roll`) and the controller does not take it
        # as travel
        self._rolled = False

    # --- commands ------------------------------------------------------------------------------------------

    def on_message(self, topic, payload, now_ms):
        """Take one MQTT message; a command that fails any check is counted, remembered and ignored."""
        if topic != self._cmd_topic:
            return
        try:
            cmd = self._codec.decode_command(self._key, topic, payload)
            if cmd["boot"] != self.boot_id:
                raise wire.WireError("command of boot %d; this is boot %d"
                                     % (cmd["boot"], self.boot_id))
            sid = cmd["sid"]
            if sid == self.sid:
                if wrap_diff(cmd["seq"], self.cseq) <= 0:
                    raise wire.WireError("replayed command: seq %d of session %d is not after %d"
                                         % (cmd["seq"], sid, self.cseq))
            elif sid in self._left_sids:
                raise wire.WireError("command of session %d, which this board has left for session %d"
                                     % (sid, self.sid))
            elif self.cmd is not None and wrap_diff(cmd["rseq"], self.cmd["rseq"]) <= 0:
                raise wire.WireError("new session %d: report %d, not after session %d's report %d"
                                     % (sid, cmd["rseq"], self.sid, self.cmd["rseq"]))
            slot = cmd["rseq"] % _HISTORY
            if self._sent_seq[slot] != cmd["rseq"]:
                raise wire.WireError("stale command: report %d not among the last %d"
                                     % (cmd["rseq"], _HISTORY))
            age_ms = wrap_diff(now_ms, self._sent_t[slot])
            if age_ms > self.cfg["max_data_age_ms"]:
                raise wire.WireError("stale command: report %d is %d ms old (limit %d ms)"
                                     % (cmd["rseq"], age_ms, self.cfg["max_data_age_ms"]))
            if self.enc_fail_ms is not None and wrap_diff(self._sent_t[slot], self.enc_fail_ms) <= 0:
                raise wire.WireError("from before the encoder failed")   # its odometer is lost
            if cmd["eoa_mm"] - self.odo_mm > self.cfg["max_authority_mm"]:   # no line is that long: a zone error
                raise wire.WireError("eoa over max_authority_mm ahead")
            if cmd["dir"] != (self.way < 0):   # the last check: a turn, taken standing only (undriven: not held)
                if self.duty_pct or wrap_diff(now_ms, self._last_move_ms) < _STAND_MS:
                    raise wire.WireError("turn while moving")
                # the motor drives the other way, a two-channel encoder counts travel up the new way (the odometer
                # runs on), and nothing driven or reached in the old direction is kept (undriven, it holds no roll)
                self.way = self.encoder.way = -self.way
                self._peak_mm = self.odo_mm
                self._brake()
        except wire.WireError as exc:
            self.rejected += 1
            self.last_reject = exc.reason
            self._rejected_since_report = True
            return
        if sid != self.sid:   # sessions only move forward: the one left is never taken again
            if self.sid >= 0:
                self._left_sids = (self._left_sids + (self.sid,))[-_LEFT_SIDS:]
            self.sid = sid
        self.cseq = cmd["seq"]
        self.cmd = cmd
        self.cmd_expiry_ms = wrap_add(self._sent_t[slot], cmd["ttl_ms"])
        self.eoa_mm = cmd["eoa_mm"]

    def command_valid(self, now_ms):
        return self.cmd is not None and wrap_diff(now_ms, self.cmd_expiry_ms) < 0

    # --- the loop -----------------------------------------------------------------------------------------------

    def step(self, now_ms):
        """One pass of the loop at board time `now_ms` (ms, modulo 2^30: wire.wrap_diff compares board times)."""
        if self._last_step_ms is None:   # the first pass: the board's times start now, whatever its clock reads
            self._last_step_ms = self._last_move_ms = now_ms
            self._report_slot_ms = wrap_add(now_ms, -self.cfg["report_ms"])
        dt_s = wrap_diff(now_ms, self._last_step_ms) / 1000.0
        self._last_step_ms = now_ms
        self._sample(now_ms)
        # after a stall (a WiFi reconnect, a long collection) the loop did not act in between: its reference ramp,
        # integral and encoder checks take at most 0.1 s of it, or a ramp run on alone trips the drive-ceiling check
        self._control(now_ms, dt_s if dt_s < 0.1 else 0.1)
        if self.duty_pct == 0:   # braked or not driven at this pass: the next report says so if it drives by then
            self._undriven = True
        self._duty_acc += 0x10000 + self.duty_pct
        # a report is due a period after the previous one's slot, the period being the valid command's `rpt_ms` (the
        # controller asks for faster reports while a train behind follows this one closely) or the board's own: it
        # is chosen at every pass, so a command that expires or changes it takes effect at once. Slots keep the
        # cadence (a loop period that does not divide the report period must not stretch it) and restart after a stall
        period = self.cfg["report_ms"]
        if self.command_valid(now_ms) and self.cmd["rpt_ms"]:
            period = self.cmd["rpt_ms"]
        due = wrap_add(self._report_slot_ms, period)
        if wrap_diff(now_ms, due) >= 0:
            self._report(now_ms)
            self._report_slot_ms = due if wrap_diff(wrap_add(due, period), now_ms) > 0 else now_ms

    def _sensor_failed(self, name, exc):
        self.sensor_errors += 1
        self.last_sensor_error = "%s: %s" % (name, exc)

    def _encoder_failed(self, now_ms, why):
        """Hold the train braked (mode trip) for _ENC_HOLD_MS from now, and drop its command: once the hold is over it
        moves only on a new one, which the controller sends once it has located the train afresh."""
        if self.enc_fail_ms is None:
            self.enc_fails += 1
        self.enc_fail_ms = now_ms
        self.last_sensor_error = "encoder: " + why
        self._v_edge = 0
        self._ref_mm = 0.0
        self._sat_ms = 0
        if self.command_valid(now_ms):
            self.cmd_expiry_ms = now_ms

    def _sample(self, now_ms):
        # a failed sensor is counted and named, never allowed to stop the loop
        last = count = self._ring_n[self._ring_i - 1]   # a failed encoder: as if no edge came
        age_us = 0
        try:
            count = self.encoder.count()
            age_us = self.encoder.age_us   # 0 from an encoder that does not time its edges
            signed = getattr(self.encoder, "signed", False)
            if count < last and not signed:
                # one channel counts every edge up: a count that goes back is a glitch, and the odometer is lost
                self._encoder_failed(now_ms, "count went back")
            odo_mm = count * 1000 // self.cfg["counts_per_m"]
            if odo_mm != self.odo_mm:
                self._last_move_ms = now_ms
                if signed and odo_mm < self.odo_mm - _JUMP_MM:   # no train goes back that fast: a glitch
                    self._encoder_failed(now_ms, "count jumped back")
                    self._peak_mm = odo_mm
                elif signed:
                    self._back_check(odo_mm)
                elif self.duty_pct == 0 and self.v_ref_mmps <= 0:   # braked to a standstill (or tripped) since the
                    self._rolled = True                              # last pass: not travel the board drove
            self.odo_mm = odo_mm
        except Exception as exc:
            self._sensor_failed("encoder", exc)
            self._encoder_failed(now_ms, "read failed")
        if self.integrity is not None and not self.split:   # a pin read: nothing to fail
            self.split = self.integrity.value() == 1
        try:
            fix = self.ips.poll(now_ms)
            if fix is not None:
                self._ips_fix = [fix[0], fix[1], fix[2]]
        except Exception as exc:
            self._sensor_failed("ips", exc)
        try:
            uid = self.rfid.poll(now_ms)
            # the reader entered the tag's field since its previous poll that answered, `span` ms ago (time, not
            # counts: a wheel that spins or a burst of counts is not travel); a span too long for the wire tells
            # nothing, and that read is not reported
            span = 0 if self._rfid_ms is None else wrap_diff(now_ms, self._rfid_ms)
            self._rfid_ms = now_ms
            if uid is not None and len(self._tags) < wire.MAX_TAGS and span <= _SPAN_MAX_MS:
                tag = [uid, self.odo_mm, now_ms, span]
                data = getattr(self.rfid, "data", None)   # a balise's telegram, 32 hex digits, when the tag has one
                if data:
                    tag.append(data)
                self._tags.append(tag)
        except Exception as exc:
            self._sensor_failed("rfid", exc)
        if self.ranging is not None:
            try:
                gap = self.ranging.poll(now_ms)
                if gap is not None:
                    self.gap_mm = int(gap)
                    self.gap_t_ms = now_ms
                    self._rng_report = [now_ms, self.gap_mm]
            except Exception as exc:
                self._sensor_failed("ranging", exc)
        # speed (the M/T method): the counts between the newest edge and the newest edge at least a speed window
        # before it that has another count, over the exact time between the two. An encoder that times its edges gives
        # the newest edge's age at the read (`age_us`); one that does not stands each count at its sample (age 0). A
        # count keeps its edge's time (at most a second old: spans never wrap); no such edge in the ring: standing.
        # Integers throughout: no float for the heap to hold, small ints on a 32-bit board
        i = self._ring_i
        now_us = (now_ms & 0x3FFFF) * 1000
        edge_us = self._ring_t[i - 1]
        if count != self._ring_n[i - 1]:
            edge_us = now_us - age_us
        elif (now_us - edge_us) % _US_WRAP > 1000000:
            edge_us = now_us - 1000000
        edge_us %= _US_WRAP
        self._ring_t[i] = edge_us
        self._ring_n[i] = count
        self._ring_i = (i + 1) % _SPEED_RING
        cfg = self.cfg
        window_us = cfg["speed_window_ms"] * 1000
        v_mmps = 0
        for k in range(1, _SPEED_RING):   # unfilled slots hold count 0 at time 0: at worst a low first speed
            j = (i - k) % _SPEED_RING
            span_us = (edge_us - self._ring_t[j]) % _US_WRAP
            if span_us >= window_us and self._ring_n[j] != count:
                v_mmps = (count - self._ring_n[j]) * 1000000 // cfg["counts_per_m"] * 1000 // span_us
                break
        age_us = (now_us - edge_us) % _US_WRAP
        if age_us:
            # no edge for longer than a count takes at this speed: it is slower, at most a count over that time
            v_mmps = min(v_mmps, 1000000 // cfg["counts_per_m"] * 1000 // age_us)
        self.v_mmps = v_mmps
        # the encoder against physics and the commanded motion: from the speed at the newest count, braking at the
        # adhesion limit, the train has surely gone _ENC_COUNTS counts further by now; the speed reference has not
        # asked for enc_slack_mm (or the authority left, if less) more than that; no train runs half again faster than
        # its motor drives it unloaded
        if count != self._ring_n[i - 1]:
            self._v_edge = v_mmps
            self._ref_mm = 0.0
        elif self._v_edge:
            t_s = age_us / 1000000
            v0 = self._v_edge
            b = _ADHESION_MMPS2
            moved_mm = v0 * t_s - b * t_s * t_s / 2 if v0 > b * t_s else v0 * v0 / (2 * b)
            if moved_mm * cfg["counts_per_m"] > _ENC_COUNTS * 1000:
                self._encoder_failed(now_ms, "no count for %d ms at %d mm/s" % (age_us // 1000, v0))
        # the slack is at most the authority left: a train driven that far with no count may have reached its end
        slack_mm = min(cfg["enc_slack_mm"], max(0, self.eoa_mm - self.odo_mm))
        if self._ref_mm * cfg["counts_per_m"] > slack_mm * cfg["counts_per_m"] + _ENC_COUNTS * 1000:
            self._encoder_failed(now_ms, "no count in %d mm the train was driven" % self._ref_mm)
        if abs(v_mmps) * 2 > cfg["v_noload_mmps"] * 3:
            self._encoder_failed(now_ms, "%d mm/s, faster than the motor drives" % v_mmps)

    def _back_check(self, odo_mm):
        """Roll-away and reverse-movement protection (two channels: the odometer is signed)."""
        if self.reverse:
            return
        if odo_mm > self._peak_mm:
            self._peak_mm = odo_mm
        back_mm = self._peak_mm - odo_mm
        if self.holding:
            if back_mm <= _HOLD_DONE_MM:
                self.holding = False
            elif back_mm > 3 * _BACK_MM:   # driven forward, it still goes back: not a roll the motor holds
                self.reverse = True
        elif back_mm > _BACK_MM:
            if self.duty_pct > 0:
                self.reverse = True
            else:
                self.holding = True
                self.holds += 1

    def odo_scale(self):
        """Odometer mm per true mm, a low bound from the newest command (1.0 before any): the curves below work in
        odometer units, so their decelerations (true m/s^2) are scaled by it. A wheel that reads long then brakes no
        earlier than it must; one that reads short still stops within its authority on the trip curve."""
        cmd = self.cmd
        return 1.0 if cmd is None else cmd["odo_mm_per_m"] / 1000.0

    def braking_curve_mmps(self, dec_mmps2):
        """The service curve: highest speed (mm/s) from which braking at `dec_mmps2` stops the train at its end of
        authority less the stop window, and at its stop target. The speed loop rides it; safety rests on the trip
        curve above it, which supervises the end of authority alone (a station stop is service, not safety)."""
        end_mm = self.eoa_mm - self.cfg["stop_window_mm"] * self.odo_scale()
        cmd = self.cmd
        if cmd is not None and cmd["stop_mm"] < end_mm:   # the stop target of the newest command (a station)
            end_mm = cmd["stop_mm"]
            if self.duty_pct == 0 and end_mm - self.odo_mm <= STOP_MADE_MM:
                return 0.0   # braking (or braked) onto the mark: stop here rather than drive the last mm again
        dist_mm = end_mm - self.odo_mm
        if dist_mm <= 0:
            return 0.0
        v = sqrt(2.0 * dec_mmps2 * self.odo_scale() * dist_mm)
        return v if v >= _CREEP_MMPS else 0.0   # the last fraction of a mm: stop and hold rather than creep

    def trip_curve_mmps(self):
        """The emergency curve: highest speed v (mm/s) from which the motor brake still stops the train at its end of
        authority after the reaction time r: v r + v^2 / (2 b) = distance, b the emergency deceleration. Above it the
        unit trips. It lies above the service curve everywhere, so riding the service curve never trips."""
        dist_mm = self.eoa_mm - self.odo_mm
        if dist_mm <= 0:
            return 0.0
        b = self.cfg["emergency_dec_mmps2"] * self.odo_scale()
        r = self.cfg["reaction_ms"] / 1000.0
        return b * (sqrt(r * r + 2.0 * dist_mm / b) - r)

    def guard_limit_mm(self):
        """Shortest measured gap (mm) the guard accepts at the current speed: emergency braking distance, reaction
        distance and the guard margin."""
        cfg = self.cfg
        v = max(0, self.v_mmps)
        return v * v / (2.0 * cfg["emergency_dec_mmps2"]) + v * cfg["reaction_ms"] / 1000.0 + cfg["guard_margin_mm"]

    def _control(self, now_ms, dt_s):
        cfg = self.cfg
        # collision guard: a fresh measured gap below guard_limit_mm brakes whatever the commands say
        if (self.gap_mm is not None and wrap_diff(now_ms, self.gap_t_ms) <= cfg["guard_fresh_ms"]
                and self.gap_mm < self.guard_limit_mm()):
            if not self.guard_on:
                self.guard_trips += 1
            self.guard_on = True
            self.mode = "trip"
            self._brake()
            return
        if self.guard_on:
            self.guard_on = False
        if self.enc_fail_ms is not None:   # a failed encoder: braked until _ENC_HOLD_MS after its last sign
            if wrap_diff(now_ms, self.enc_fail_ms) < _ENC_HOLD_MS:
                self.mode = "trip"
                self._brake()
                return
            self.enc_fail_ms = None
        if self.reverse or self.split:
            # it ran backwards when driven (a drive may run it backwards again), or a car came off: braked for good
            self.holding = False
            self.mode = "trip"
            self._brake()
            return
        if self.holding:
            # rolling back undriven (a slope the brake does not hold): driven forward, harder the further it went, to
            # where it stood and no further (_back_check ends the hold); never past ground it had reached
            self._held = True
            self.v_ref_mmps = 0.0
            self.duty_pct = min(60, 10 + self._peak_mm - self.odo_mm)
            self.motor.drive(self.way * self.duty_pct)
            return
        if self.command_valid(now_ms):
            cmd = self.cmd
            # speeds and rates are true mm/s and mm/s^2; the loop runs on the odometer, which reads the command's
            # low bound of its scale long or more: at most line speed in truth, and near it
            scale = self.odo_scale()
            v_cap = min(cmd["v_mmps"], cfg["v_max_mmps"]) * scale
            acc = cmd["acc"] * scale
            dec = cmd["dec"] * scale
            mode = "run"
        else:
            v_cap = 0
            acc = cfg["acc_mmps2"]
            dec = cfg["dec_mmps2"]
            mode = "idle" if self.cmd is None else "stop"
        v_curve = self.braking_curve_mmps(cfg["dec_mmps2"])
        if self.mode == "trip":
            if self.v_mmps > 0:
                self._brake()
                return
            self.mode = mode
        trip_mmps = self.trip_curve_mmps()
        if self.v_mmps > trip_mmps + cfg["trip_margin_mmps"]:
            self.trips += 1
            self.mode = "trip"
            self._brake()
            return
        self.mode = mode
        # the speed reference ramps to the commanded speed at the commanded rates and rides the service curve where it
        # is lower: behind an advancing end of authority that is Takagi's law beta_s (v - v_ahead) / v (protocol.md)
        v_before = self.v_ref_mmps
        if v_cap > v_before:
            self.v_ref_mmps = min(v_cap, v_before + acc * dt_s)
        else:
            self.v_ref_mmps = max(v_cap, v_before - dec * dt_s)
        if self.v_ref_mmps > v_curve:
            self.v_ref_mmps = v_curve
        a_ref = (self.v_ref_mmps - v_before) / dt_s if dt_s > 0 else 0.0
        if self.v_ref_mmps <= 0:   # a standstill target: brake (stop and hold), do not coast
            self._brake()
            return
        # the measured speed is the mean between two edges at least a speed window apart, so it lags about half a
        # window: compare it with the reference of then (ramps would otherwise wind the integral up and overshoot)
        error = self.v_ref_mmps - a_ref * cfg["speed_window_ms"] / 2000.0 - self.v_mmps
        # the integral learns the steady offset (friction, load, a tired battery), also while the reference steps with
        # each end of authority behind a moving train, but not in a sustained ramp (the reference's slope, low-passed
        # over 0.1 s, beyond 200 mm/s^2), where a traction-limited start would wind it up
        self._a_lp += (a_ref - self._a_lp) * dt_s / (dt_s + 0.1)
        if -200.0 < self._a_lp < 200.0:
            self._integral += error * dt_s
            limit = 100.0 / cfg["ki"]
            self._integral = max(-limit, min(limit, self._integral))
        # feed-forward of speed and acceleration through the first-order motor, then PI on the speed error, at most
        # drive_margin_pct above the feed-forward: whatever the encoder reads, the motor is never driven much harder
        # than the reference needs. A train held at that ceiling and still slower than the reference for _SAT_MS is
        # not where its encoder says: the encoder reads short
        ff = (self.v_ref_mmps + a_ref * cfg["motor_tau_ms"] / 1000.0) * 100.0 / cfg["v_noload_mmps"]
        duty = ff + cfg["kp"] * error + cfg["ki"] * self._integral
        if duty > ff + cfg["drive_margin_pct"]:
            duty = ff + cfg["drive_margin_pct"]
            if error > 0 and -200.0 < self._a_lp < 200.0:   # the integral does not wind up against the ceiling
                self._integral -= error * dt_s
            if self.v_mmps < self.v_ref_mmps - _SLOW_MMPS:
                self._sat_ms += int(dt_s * 1000)
                if self._sat_ms > _SAT_MS:
                    self._encoder_failed(now_ms, "%d mm/s at full drive for %d mm/s" % (self.v_mmps, self.v_ref_mmps))
                    self.mode = "trip"
                    self._brake()
                    return
        else:
            self._sat_ms = 0
        if self.v_mmps > trip_mmps:
            # over the trip curve, within its margin (the end of authority stopped moving or stepped back under a
            # train riding its service curve): brake at this pass, whatever duty a lagging loop still asks
            duty = -1
        if duty < 0 and self.v_mmps > 0:
            # the motor's own drag at zero duty (v / tau: weak at low speed) is less braking than the curve asks:
            # short the windings for this pass (brake: it cannot reverse the train, as a negative duty could)
            self.duty_pct = 0
            self.motor.brake()
            return
        duty_pct = int(max(0.0, min(100.0, duty)))
        if duty_pct > 0:   # the travel asked counts only while the motor drives: a braked train stops short of it
            self._ref_mm += self.v_ref_mmps * dt_s
        if duty_pct > 30 >= self.duty_pct:   # the stall clock runs from when the drive is applied, not from standstill
            self._last_move_ms = now_ms
        self.duty_pct = duty_pct
        self.motor.drive(self.way * duty_pct)

    def _brake(self):
        self._ref_mm = 0.0   # braked, the reference asks no travel: none carried over to the next start
        self.v_ref_mmps = 0.0
        self._integral = 0.0
        self._a_lp = 0.0
        self.duty_pct = 0
        self.motor.brake()

    # --- reporting ----------------------------------------------------------------------------------------------

    def _report(self, now_ms):
        faults = []
        last_fix = getattr(self.ips, "last_fix_ms", None)
        if last_fix is None or wrap_diff(now_ms, last_fix) > self.cfg["ips_silent_ms"]:
            faults.append("ips_silent")
        if getattr(self.ips, "crc_errors", 0):
            faults.append("ips_crc")
        if not getattr(self.rfid, "present", True):
            faults.append("rfid_absent")
        if self.duty_pct > 30 and wrap_diff(now_ms, self._last_move_ms) > self.cfg["stall_ms"]:
            faults.append("enc_stall")
        if self.enc_fail_ms is not None:
            faults.append("enc_fail")
        if self.cmd is not None and not self.command_valid(now_ms):
            faults.append("cmd_timeout")
        if self._rejected_since_report:
            faults.append("cmd_reject")
        if not self.link_ok:
            faults.append("broker_lost")
        if self.guard_on:
            faults.append("guard")
        if self._rolled:
            faults.append("roll")
            self._rolled = False
        if self._held:
            faults.append("hold")
            self._held = self.holding
        if self.reverse:
            faults.append("reverse")
        if self.split:
            faults.append("split")
        # the mean duty (floored) of the passes since the last report (this one at least): the motor answers the mean
        # (it is linear in duty), where one pass's duty of a loop that alternates would tell of a speed it never had
        acc = self._duty_acc
        self._duty_acc = 0
        duty_pct = (acc & 0xFFFF) // (acc >> 16)
        if self._undriven and duty_pct > 0 and self.mode == "run":
            # a duty above 0, but not driven at every pass since the last report (braked at this pass or one before):
            # its speed may have fallen as fast as the brake allows, which the mean duty alone would not tell
            faults.append("undriven")
        self._undriven = False
        self.faults = faults
        seq = self.seq
        slot = seq % _HISTORY
        self._sent_seq[slot] = seq
        self._sent_t[slot] = now_ms
        payload = self._codec.encode_report(self._key, self.train_id, self.boot_id, seq, now_ms, self.odo_mm,
                                            self.v_mmps, duty_pct, self.mode, self.cseq, self.sid, self._ips_fix,
                                            self._tags, self.faults, self._rng_report, self.way)
        self.seq = wrap_add(seq, 1)
        self._ips_fix = None
        if self._rng_report is not None:
            self._rng_report = None
        self._tags = []
        self._rejected_since_report = False
        try:
            self._publish(self._report_topic, payload)
        except Exception as exc:  # the shell owns reconnecting; a lost report is not fatal
            self.link_ok = False
            self.last_sensor_error = "publish: %s" % exc

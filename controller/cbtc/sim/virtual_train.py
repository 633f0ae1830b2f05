"""A virtual train: true physics + simulated drivers + the firmware's own OnboardUnit, on a bus client.

The OnboardUnit is the very class that runs on the board (firmware/obu.py); only its drivers are simulated
(`ranging`: an optional train-to-train ranging driver, cbtc.sim.ranging, which arms the onboard collision guard). The
scheduler calls `tick(now_s)` every loop period; the board's clock is the scheduler's plus a per-train offset, so
nothing may assume the two sides share a clock.
"""

import hashlib

from cbtc.firmware import obu as obu_module
from cbtc.protocol import fast_wire, wire
from cbtc.railway import physics
from cbtc.railway.legs import turned_head_s, turned_leg
from cbtc.sim.drivers import SimEncoder, SimIps, SimMotor, SimRfid, SimTrainLine


class VirtualTrain:
    def __init__(self, train_id, key, layout, profile, s0_m, client, rng, clock_offset_ms=0, obu_overrides=None,
                 ranging=None):
        self.train_id = train_id
        self.layout = layout
        self.profile = profile
        self.client = client
        self.s0_m = float(s0_m)
        self.length_m = profile.length_m   # in truth (faults length_wrong, car_dropped change it; the zone's stays)
        self.tail_car = None       # a car come off the train's tail (fault car_dropped): the tail beacon went with it
        self.travelled_m = 0.0
        self.v_mps = 0.0
        self.a_mps2 = 0.0
        self.clock_offset_ms = int(clock_offset_ms)
        self.encoder = SimEncoder(profile, rng)
        self.ips = SimIps(profile, layout, rng)
        self.rfid = SimRfid(profile, layout, rng)
        self.motor = SimMotor()
        self.train_line = SimTrainLine() if profile.integrity_loop else None
        self._key = key
        self._config = profile.obu_config()
        # the board refuses an end of authority further ahead than its line allows: the layout's length, in odometer
        # mm at a wheel that reads 10 % long
        self._config["max_authority_mm"] = int(layout.length_m * 1100.0)
        self._config.update(obu_overrides or {})
        self._ranging = ranging
        self.boots = 0
        self.obu = self._boot()
        self._last_s = None
        self._now_s = 0.0
        self.frozen = False  # a dead board: no loop, no reports, motor state as it was
        self.stopped_dead = False  # fault injection: the train stopped without braking (derailment, obstacle)
        self._rollback_m = 0.0     # fault injection: still to roll back while standing undriven, at _rollback_mps
        self._rollback_mps = 0.0
        self._reverse_m = 0.0      # fault injection: still to run backwards under the motor's drive (wired reversed)
        self._back_v_mps = 0.0     # speed backwards (m/s, >= 0; the forward speed is v_mps, one of the two is 0)
        self.route = None          # on a network: the Route of its frame
        self.legs = None           # on a line it reverses on: its legs (cbtc.railway.legs), `leg` the one it runs
        self.leg = 0
        self.cab = 1               # which end leads on its frame: 1 the end that led at the start, -1 the other
        self.turns = 0             # times it reversed
        client.subscribe(wire.topic_command(train_id), self._on_command)
        client.on_connect = self._on_connect

    @property
    def head_s(self) -> float:
        """True head position along the track (m, wrapped on loops)."""
        return self.layout.wrap(self.s0_m + self.travelled_m)

    @property
    def tail_s(self) -> float:
        return self.layout.wrap(self.s0_m + self.travelled_m - self.length_m)

    @property
    def beacon_s(self) -> float:
        """True position of the beacon on the train's last car: its tail, or a dropped car's."""
        return self.tail_s if self.tail_car is None else self.tail_car.tail_s

    def _boot(self):
        """A fresh OnboardUnit with the next boot id: drawn from the key and the boot count, so a seeded run repeats
        and every reboot differs."""
        self.boots += 1
        digest = hashlib.sha256(b"boot/%d/" % self.boots + self._key).digest()
        boot_id = (int.from_bytes(digest[:4], "big") & wire.BOOT_MAX) or 1
        unit = obu_module.OnboardUnit(self.train_id, self._key, boot_id, self.encoder, self.ips, self.rfid,
                                      self.motor, self._publish, self._config, self._ranging, fast_wire)
        if self.train_line is not None:
            unit.integrity = self.train_line
        return unit

    def reboot(self, now_s: float):
        """The board restarts at `now_s`: a new boot id, the odometer from zero, the board's clock from zero."""
        self.encoder.distance_m = 0.0
        self.encoder.way = 1     # its encoder driver starts afresh: travel is the train's forward
        self.clock_offset_ms = -int(round(now_s * 1000))
        self.ips.restart()
        self.obu = self._boot()

    def board_ms(self, now_s: float) -> int:
        return (int(round(now_s * 1000)) + self.clock_offset_ms) & wire.WRAP_MASK   # wraps as a board's time does

    def _publish(self, topic, payload):
        self.client.publish(topic, payload)

    def _on_command(self, topic, payload):
        self.obu.on_message(topic, payload, self.board_ms(self._now_s))

    def _on_connect(self, client):
        client.subscribe(wire.topic_command(self.train_id), self._on_command)

    def carry(self, distance_m: float) -> None:
        """Fault injection: the train is lifted and put down `distance_m` further along the track (negative: back),
        standing; its wheel turns not at all on the way."""
        self.s0_m += distance_m
        self.v_mps = self.a_mps2 = 0.0

    def stop_dead(self) -> None:
        """Fault injection: the train stops at once where it is and stays (the brick-wall case)."""
        self.stopped_dead = True
        self.v_mps = 0.0
        self.a_mps2 = 0.0

    def roll_back(self, distance_m: float, v_mps: float) -> None:
        """Fault injection: while the train stands undriven, it rolls back at `v_mps` until it has rolled `distance_m`
        (a slope its brakes do not hold; a drive forward holds it, and the roll goes on when it stands undriven
        again); a one-channel encoder counts the roll as forward travel."""
        self._rollback_m, self._rollback_mps = distance_m, v_mps

    @property
    def drive_pct(self) -> int:
        """The motor's duty the way the train runs on its frame (negative: driven the other way)."""
        return self.motor.duty_pct * self.cab

    def _turn(self) -> None:
        """Standing, its board turned: it runs the other end first, on its next leg (the head where the tail
        was); its sensors stay on the end they are fitted to, and read on the leg's `sensors` frame."""
        old = self.legs[self.leg]
        self.leg = turned_leg(self.legs, self.leg, self.s0_m + self.travelled_m, self.length_m)
        self.turns += 1
        new = self.legs[self.leg]
        self.s0_m = turned_head_s(old, new, self.s0_m + self.travelled_m, self.length_m) - self.travelled_m
        self.layout, self.route = new.frame, new.route
        self.cab = self.encoder.cab = -1 if new.backwards else 1
        self.ips.use_layout(new.sensors)
        self.rfid.use_layout(new.sensors)

    @property
    def rolling_back(self) -> bool:
        """A roll is left to go and the train stands undriven: it rolls back now."""
        return self._rollback_m > 1e-9 and self.v_mps == 0.0 and self.drive_pct <= 0

    @property
    def rollback_left_m(self) -> float:
        return self._rollback_m

    def _roll(self, dt_s: float) -> None:
        ds_m = min(self._rollback_m, self._rollback_mps * dt_s)
        self.travelled_m -= ds_m
        self._rollback_m -= ds_m
        self.encoder.advance(-ds_m, dt_s, self._rollback_mps, 0.0)

    def run_reversed(self, distance_m: float) -> None:
        """Fault injection: from now the motor drives the train backwards (its wires swapped) until it has run
        `distance_m` backwards; then it drives forward again. A one-channel encoder counts either way up."""
        self._reverse_m = distance_m

    @property
    def reversing(self) -> bool:
        return self._reverse_m > 1e-9 or self._back_v_mps > 0.0

    def _reverse_step(self, dt_s: float) -> None:
        """Physics on a signed speed while the motor is reversed (or the train still runs backwards after it)."""
        p, motor = self.profile, self.motor
        u = self.v_mps - self._back_v_mps
        way = 1.0 if u > 0 else -1.0 if u < 0 else 0.0
        if motor.mode != "drive" or self.drive_pct <= 0:
            a = -way * (p.beta_e_mps2 if motor.mode == "brake" else p.friction_mps2)
        else:
            target = self.drive_pct / 100.0 * p.v_noload_mps * (-1.0 if self._reverse_m > 1e-9 else 1.0)
            drive = (target - u) / p.motor_tau_s
            if way == 0.0 and abs(drive) <= p.friction_mps2:
                a = 0.0
            else:
                a = drive - (way or (1.0 if drive > 0 else -1.0)) * p.friction_mps2
                a = max(-p.beta_e_mps2, min(p.beta_e_mps2, a))
                if a * (way or a) > 0:   # speeding up (either way): the traction limit
                    a = max(-p.accel_max_mps2, min(p.accel_max_mps2, a))
        u_next = u + a * dt_s
        if way != 0.0 and u_next * way < 0.0 and (motor.mode != "drive" or self.drive_pct <= 0):
            ds_m = 0.5 * u * (u / -a)   # brakes (or coasts) to a stand inside the step
            u_next = 0.0
        else:
            ds_m = 0.5 * (u + u_next) * dt_s
        self.travelled_m += ds_m
        if ds_m < 0.0:
            self._reverse_m = max(0.0, self._reverse_m + ds_m)
        self.encoder.advance(ds_m, dt_s, abs(u), a if ds_m >= 0.0 else -a)   # along the way it went
        self.v_mps, self._back_v_mps, self.a_mps2 = max(0.0, u_next), max(0.0, -u_next), a

    def tick(self, now_s: float) -> None:
        """Advance physics to `now_s` under the motor command, then run one OnboardUnit loop."""
        dt_s = 0.0 if self._last_s is None else now_s - self._last_s
        self._last_s = now_s
        self._now_s = now_s
        if self.legs is not None and self.v_mps == 0.0 and self.encoder.way != self.cab and self.motor.duty_pct \
                and not self.reversing:
            self._turn()   # its board drives it the other way, standing (it told its encoder so): the other end leads
        if dt_s > 0 and self.reversing and not self.stopped_dead:
            self._reverse_step(dt_s)
        elif dt_s > 0 and self.rolling_back:
            self._roll(dt_s)
        elif dt_s > 0 and not self.stopped_dead:
            s_before, v_before = self.travelled_m, self.v_mps
            self.travelled_m, self.v_mps, self.a_mps2 = physics.step(
                self.travelled_m, self.v_mps, self.drive_pct, self.motor.mode, dt_s, self.profile)
            self.encoder.advance(self.travelled_m - s_before, dt_s, v_before, self.a_mps2)
        elif dt_s > 0:
            self.encoder.advance(0.0, dt_s)
        if self.frozen:
            return
        now_ms = self.board_ms(now_s)
        head_s = self.head_s
        self.ips.sample(now_ms, head_s)
        self.rfid.sense(head_s)
        self.obu.step(now_ms)

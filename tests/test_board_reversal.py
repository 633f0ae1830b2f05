"""A board reverses only standing, on a fresh sealed command naming the new direction: it drives the motor the other
way, counts its odometer on (up in the new direction) and keeps nothing of the old direction's authority. The same
scenario runs under the MicroPython unix port."""

from cbtc.firmware import obu
from cbtc.protocol import wire_zc
from fake_drivers import FakeEncoder, FakeIps, FakeMotor, FakeRfid
from test_firmware_mpy import PRELUDE, compiled_firmware, run_mpy  # noqa: F401  (the module's fixture builds the .mpy)

KEY = b"0123456789abcdef"
CMD = "cbtc/train/A/cmd"


class SignedEncoder(FakeEncoder):
    """Two channels: the wheel turning backwards counts down, or up while the board says it travels backwards (`way`
    -1, as firmware/drivers/encoder.py does)."""
    signed = True
    way = 1

    def __init__(self):
        super().__init__()
        self.wheel_mm = 0   # where the wheel has turned to: up forwards, down backwards

    def turn_to(self, wheel_mm):
        self.counts += (wheel_mm - self.wheel_mm) * self.way
        self.wheel_mm = wheel_mm


class Shuttle:
    """A board on a signed encoder whose wheel turns the way the motor drives it (1 count per mm)."""

    def __init__(self):
        self.sent = []
        self.enc = SignedEncoder()
        self.motor = FakeMotor()
        self.unit = obu.OnboardUnit("A", KEY, 9, self.enc, FakeIps(), FakeRfid(), self.motor,
                                    lambda topic, payload: self.sent.append((topic, payload)), {"counts_per_m": 1000})
        self.now_ms, self.seq, self._travel_mm = 0, 0, 0.0

    def step(self, ms=20):
        """Advance 20 ms with the wheel at the speed the board's reference asks, the way its motor drives."""
        self.now_ms += ms
        way = -1 if self.motor.mode == "drive" and self.motor.duty_pct < 0 else 1
        if self.motor.mode == "drive" and self.motor.duty_pct:
            self._travel_mm += way * self.unit.v_ref_mmps * ms / 1000.0
        self.enc.turn_to(int(self._travel_mm))
        self.unit.step(self.now_ms)

    def report(self):
        return wire_zc.decode_report(KEY, self.sent[-1][0], self.sent[-1][1])

    def command(self, eoa_mm, direction, v_mmps=300):
        self.seq += 1
        payload = wire_zc.encode_command(KEY, "A", 9, self.seq, 1, self.report()["seq"], v_mmps, eoa_mm, 800, 600,
                                         800, dir=direction)
        self.unit.on_message(CMD, payload, self.now_ms)

    def run(self, eoa_mm, direction, seconds):
        for _ in range(int(seconds * 50)):
            if self.now_ms % 100 == 0:
                self.command(eoa_mm, direction)
            self.step()


def test_a_board_refuses_a_change_of_direction_while_it_moves_and_keeps_its_authority():
    shuttle = Shuttle()
    shuttle.step()
    shuttle.run(2000, 0, 1.0)
    assert shuttle.unit.v_mmps > 100
    rejected = shuttle.unit.rejected
    shuttle.command(shuttle.unit.odo_mm + 500, 1)
    assert shuttle.unit.rejected == rejected + 1 and "turn while moving" in shuttle.unit.last_reject
    assert shuttle.unit.way == 1 and shuttle.unit.eoa_mm == 2000


def test_a_board_reverses_standing_drives_the_other_way_and_counts_its_odometer_on():
    shuttle = Shuttle()
    shuttle.step()
    shuttle.run(600, 0, 6.0)                      # runs to its end of authority at 600 mm and stands there
    assert 560 <= shuttle.unit.odo_mm <= 600
    shuttle.run(shuttle.unit.odo_mm, 0, 1.0)      # held where it stands: standing for a second
    odo = shuttle.unit.odo_mm
    wheel = shuttle.enc.wheel_mm
    shuttle.run(odo + 400, 1, 6.0)                # reversed: 400 mm ahead in the new direction
    unit = shuttle.unit
    assert unit.way == -1 and unit.rejected == 0 and not unit.reverse and unit.mode == "run"
    assert odo + 360 <= unit.odo_mm <= odo + 400          # the odometer counted up, to the new end of authority
    assert wheel - 400 <= shuttle.enc.wheel_mm <= wheel - 360   # while the wheel turned backwards
    assert shuttle.report()["odo_mm"] == unit.odo_mm


def test_nothing_of_the_old_direction_survives_a_reversal():
    shuttle = Shuttle()
    shuttle.step()
    shuttle.run(300, 0, 5.0)
    shuttle.run(shuttle.unit.odo_mm, 0, 1.0)
    stood = shuttle.unit.odo_mm
    shuttle.command(stood, 1)                     # reversed with no authority: it stays where it is
    assert shuttle.unit.way == -1 and shuttle.unit.eoa_mm == stood
    for _ in range(100):
        shuttle.step()
    assert shuttle.motor.mode == "brake" and shuttle.unit.odo_mm == stood


def test_reversal_under_micropython():
    script = PRELUDE + """
enc.signed = True
enc.way = 1
WHEEL = [0]
def turn_to(mm):
    enc.n += (mm - WHEEL[0]) * enc.way
    WHEEL[0] = mm
def tick(n, eoa, d):
    t = [0]
    for i in range(n):
        t[0] += 20
        now = STEP[0] + t[0]
        way = -1 if motor.mode == "drive" and motor.duty_pct < 0 else 1
        if motor.mode == "drive" and motor.duty_pct:
            TRAVEL[0] += way * unit.v_ref_mmps * 20 / 1000
        turn_to(int(TRAVEL[0]))
        if now % 100 == 0:
            r = last_report() if sent else None
            if r is not None:
                SEQ[0] += 1
                unit.on_message("cbtc/train/A/cmd", wire_zc.encode_command(KEY, "A", 9, SEQ[0], 1, r["seq"], 300,
                                eoa, 800, 600, 800, dir=d), now)
        unit.step(now)
    STEP[0] += t[0]
STEP = [0]; TRAVEL = [0.0]; SEQ = [0]
unit.step(0)
tick(300, 600, 0)
tick(50, unit.odo_mm, 0)
odo = unit.odo_mm
assert 560 <= odo <= 600 and motor.mode == "brake", odo
tick(300, odo + 400, 1)
assert unit.way == -1 and unit.rejected == 0 and not unit.reverse, (unit.way, unit.rejected, unit.last_reject)
assert odo + 360 <= unit.odo_mm <= odo + 400 and WHEEL[0] < 300, (unit.odo_mm, WHEEL[0])
print("OK")
"""
    rc, out, err = run_mpy(script, heap="64K")
    assert rc == 0 and "OK" in out, (out, err)

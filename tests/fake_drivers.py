"""Minimal scripted drivers for OnboardUnit tests (CPython)."""


class FakeEncoder:
    age_us = 0          # does not time its edges

    def __init__(self):
        self.counts = 0

    def count(self):
        return self.counts


class TimedEncoder(FakeEncoder):
    """An encoder that times its edges, as the board's does: `age_us`, us since the newest edge, set by the test."""


class FakeIps:
    def __init__(self):
        self.fix = None
        self.last_fix_ms = None
        self.crc_errors = 0

    def poll(self, now_ms):
        fix, self.fix = self.fix, None
        if fix is not None:
            self.last_fix_ms = now_ms
        return fix


class FakeRfid:
    def __init__(self):
        self.uid = None
        self.present = True

    def poll(self, now_ms):
        uid, self.uid = self.uid, None
        return uid


class BrokenSensor:
    """A sensor whose bus has gone: every call raises OSError, as an unplugged I2C/SPI/UART device does."""

    present = False
    last_fix_ms = None

    def count(self):
        raise OSError(19, "ENODEV")

    def poll(self, now_ms):
        raise OSError(19, "ENODEV")


class FakeMotor:
    def __init__(self):
        self.mode = "coast"
        self.duty_pct = 0

    def drive(self, duty_pct):
        self.mode, self.duty_pct = "drive", duty_pct

    def brake(self):
        self.mode, self.duty_pct = "brake", 0

    def coast(self):
        self.mode, self.duty_pct = "coast", 0

"""DC motor on an H-bridge driven by two PWM pins (DRV8833 / L9110S style: IN1, IN2).

Motor(pwm_a, pwm_b) takes ready `machine.PWM` objects. Signed duty in percent: positive drives IN1 with PWM and holds
IN2 low (forward), negative the other way round. coast(): both inputs low (the bridge is open, the train rolls);
brake(): both inputs high (the motor windings are shorted: the train stops hard). Works with `duty_u16` (newer ports)
and with the ESP8266's 10-bit `duty` (0..1023).
"""

try:
    from micropython import const
except ImportError:  # CPython
    def const(value):
        return value

_FULL_U16 = const(65535)   # duty_u16 full scale
_FULL_10 = const(1023)     # ESP8266 duty() full scale


class Motor:
    def __init__(self, pwm_a, pwm_b):
        self.pwm_a = pwm_a
        self.pwm_b = pwm_b
        self._u16 = hasattr(pwm_a, "duty_u16")
        self.duty_pct = 0
        self.mode = "coast"
        self.coast()

    def _set(self, pwm, duty_pct):
        """Set `pwm` to a duty given in percent (0..100), rounded to the nearest step."""
        if self._u16:
            pwm.duty_u16((duty_pct * _FULL_U16 + 50) // 100)
        else:
            pwm.duty((duty_pct * _FULL_10 + 50) // 100)

    def drive(self, duty_pct):
        """Apply a signed duty (%); clamped to [-100, 100]; positive is forward."""
        pct = int(max(-100, min(100, duty_pct)))
        if pct >= 0:
            self._set(self.pwm_b, 0)
            self._set(self.pwm_a, pct)
        else:
            self._set(self.pwm_a, 0)
            self._set(self.pwm_b, -pct)
        self.duty_pct = pct
        self.mode = "drive"

    def coast(self):
        """Both inputs low: no drive, no braking."""
        self._set(self.pwm_a, 0)
        self._set(self.pwm_b, 0)
        self.duty_pct = 0
        self.mode = "coast"

    def brake(self):
        """Both inputs high: the windings are shorted and brake the motor."""
        self._set(self.pwm_a, 100)
        self._set(self.pwm_b, 100)
        self.duty_pct = 0
        self.mode = "brake"

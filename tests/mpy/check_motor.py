"""Motor checks that run unchanged under CPython and under the MicroPython unix port.

Each `check_*` function builds the driver on the host shims (cbtc/board/host) and asserts byte-exact behaviour;
tests/test_drivers.py calls each one directly and again inside `micropython -X heapsize=36K`.
"""

import machine

from drivers.motor import Motor


class Pwm10:
    """An ESP8266 PWM of older ports: duty() 0..1023 only."""

    def __init__(self):
        self.value = -1

    def duty(self, value):
        self.value = value


def check_motor_duty_u16():
    a = machine.PWM(machine.Pin(5), freq=1000, duty=0)
    b = machine.PWM(machine.Pin(4), freq=1000, duty=0)
    motor = Motor(a, b)
    assert motor.mode == "coast" and a.duty_u16() == 0 and b.duty_u16() == 0
    motor.drive(50)
    assert a.duty_u16() == 32768 and b.duty_u16() == 0 and motor.duty_pct == 50 and motor.mode == "drive"
    motor.drive(-25)
    assert a.duty_u16() == 0 and b.duty_u16() == 16384 and motor.duty_pct == -25
    motor.drive(250)
    assert a.duty_u16() == 65535 and motor.duty_pct == 100
    motor.drive(-400)
    assert b.duty_u16() == 65535 and a.duty_u16() == 0 and motor.duty_pct == -100
    motor.brake()
    assert a.duty_u16() == 65535 and b.duty_u16() == 65535 and motor.mode == "brake" and motor.duty_pct == 0
    motor.coast()
    assert a.duty_u16() == 0 and b.duty_u16() == 0 and motor.mode == "coast"


def check_motor_duty_10bit():
    a, b = Pwm10(), Pwm10()
    motor = Motor(a, b)
    motor.drive(50)
    assert (a.value, b.value) == (512, 0)
    motor.drive(-1)
    assert (a.value, b.value) == (0, 10)
    motor.brake()
    assert (a.value, b.value) == (1023, 1023)
    motor.coast()
    assert (a.value, b.value) == (0, 0)

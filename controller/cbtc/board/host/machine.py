"""Host stand-in for MicroPython's `machine` module (CPython and the MicroPython unix port). A real board has it
built in, at no heap cost; here it costs heap, so it holds only what the firmware uses.

Pin also stands in for PWM (duty_u16 reads back the last duty), for an SPI bus with nothing on it (MISO reads 0)
and for the watchdog (feeding it does nothing). Test hooks: UART_RX[id] holds the bytes a UART created later starts
with (its `buf` takes more); a pin keeps its `trigger` and `handler` (tests/mpy/check_encoder.py drives edges).
"""

UART_RX = {}


class Pin:
    IN = 0
    OUT = PULL_UP = IRQ_RISING = 1
    IRQ_FALLING = 2
    handler = None

    def __init__(self, *args, value=0, **_kw):
        """Pin(id, mode[, pull], value=0): a pull-up or value=1 starts high. PWM(pin, ...), SPI(id, ...)."""
        self.state = 1 if value or args[2:] else 0

    def value(self, v=None):
        if v is None:
            return self.state
        self.state = v

    duty_u16 = value   # PWM: reads back the last duty
    feed = value       # WDT: feeding does nothing (without an argument, value() only reads)

    def irq(self, trigger, handler, hard=False):
        self.trigger = trigger
        self.handler = handler
        self.hard = hard

    def write_readinto(self, data, buf):
        buf[:] = bytes(len(data))

    def write(self, data):
        pass


PWM = SPI = WDT = Pin


class UART:
    def __init__(self, n, *_args, **_kw):
        """UART(id, ...)."""
        self.buf = bytearray(UART_RX.pop(n, b""))

    def any(self):
        return len(self.buf)

    def read(self, n):
        data = bytes(self.buf[:n])
        self.buf = self.buf[n:]
        return data or None


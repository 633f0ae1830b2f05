"""Host stand-in for MicroPython's `machine` module (CPython and the MicroPython unix port), kept as small as the
firmware and the driver checks allow: it stands in for what a real board has built in, so it should cost no heap.

Test hooks: Pin.set_level fires the interrupt handler; UART_RX holds the bytes a UART created later starts with
(UART.feed adds more); SPI.attach hands every transfer to a fake device; WDT counts its feeds, WDTS holds the
watchdogs created.
"""

UART_RX = {}
WDTS = []


class Pin:
    IN = 0
    OUT = 1
    PULL_UP = 1
    IRQ_RISING = 1
    IRQ_FALLING = 2

    def __init__(self, *args, value=None):
        """Pin(id, mode[, pull], value=None): a pull-up or value=1 starts high."""
        self.state = 1 if value or args[2:] else 0
        self.handler = None

    def value(self, level=None):
        if level is None:
            return self.state
        self.state = 1 if level else 0

    def irq(self, trigger=3, handler=None):
        self.trigger = trigger
        self.handler = handler

    def set_level(self, level):
        """Test hook: drive the input to `level`; the handler runs if it listens to this edge."""
        old = self.state
        self.value(level)
        if self.handler and old != self.state and self.trigger & (1 if self.state else 2):
            self.handler(self)


class PWM:
    def __init__(self, *args, **_kw):
        self.state = 0

    def duty_u16(self, value=None):
        if value is None:
            return self.state
        self.state = value


class UART:
    def __init__(self, *args, **_kw):
        self.state = bytearray(UART_RX.pop(args[0], b""))

    def feed(self, data):
        """Test hook: bytes arriving on RX."""
        self.state.extend(data)

    def any(self):
        return len(self.state)

    def read(self, size):
        data = bytes(self.state[:size])
        self.state = self.state[size:]
        return data or None


class SPI:
    def __init__(self, *args, **_kw):
        self.state = None

    def attach(self, device):
        """Test hook: `device.transfer(tx: bytes) -> bytes` of the same length answers every transaction."""
        self.state = device

    def write_readinto(self, data, buf):
        if self.state:
            buf[:] = self.state.transfer(bytes(data))
        else:
            buf[:] = bytes(len(data))   # nothing on the bus: MISO pulled low

    def write(self, data):
        self.write_readinto(data, bytearray(len(data)))


class WDT:
    def __init__(self, *args, **_kw):
        self.feeds = 0
        WDTS.append(self)

    def feed(self):
        self.feeds += 1

"""Host stand-in for MicroPython's `machine` module (runs under CPython and the MicroPython unix port).

Enough of Pin, PWM, UART, SPI, WDT for the firmware and its drivers, plus test hooks: Pin.set_level fires the
interrupt handler, UART.feed (or UART_RX, before the board creates the UART) queues received bytes, SPI hands every
transfer to an attached fake device, WDT and reset record what happened. Instances are remembered in PINS / UARTS / SPIS / WDTS so a test can reach the board's objects.
"""

PINS = {}
UARTS = {}
UART_RX = {}        # uart id -> bytes a UART created later starts with (a test seeds what the board will receive)
SPIS = {}
WDTS = []
RESETS = []


class Pin:
    IN = 0
    OUT = 1
    PULL_UP = 1
    IRQ_RISING = 1
    IRQ_FALLING = 2

    def __init__(self, pin_id, mode=IN, pull=None, value=None):
        self.id = pin_id
        self.mode = mode
        self.pull = pull
        self._level = 1 if pull == Pin.PULL_UP else 0
        if value is not None:
            self._level = 1 if value else 0
        self._trigger = 0
        self._handler = None
        PINS[pin_id] = self

    def value(self, level=None):
        if level is None:
            return self._level
        self._level = 1 if level else 0
        return None

    def irq(self, trigger=3, handler=None):
        self._trigger = trigger
        self._handler = handler

    def set_level(self, level):
        """Test hook: drive the input to `level` and run the handler if this edge is one it listens to."""
        old = self._level
        self._level = 1 if level else 0
        if self._handler is None or old == self._level:
            return
        if (self._level and self._trigger & Pin.IRQ_RISING) or (not self._level and self._trigger & Pin.IRQ_FALLING):
            self._handler(self)


class PWM:
    def __init__(self, pin, freq=1000, duty=0, duty_u16=None):
        self.pin = pin
        self.freq_hz = freq
        self._u16 = duty * 64 if duty_u16 is None else duty_u16

    def duty(self, value=None):
        """ESP8266 style: 0..1023."""
        if value is None:
            return self._u16 // 64
        self._u16 = max(0, min(1023, value)) * 64
        return None

    def duty_u16(self, value=None):
        if value is None:
            return self._u16
        self._u16 = max(0, min(65535, value))
        return None


class UART:
    def __init__(self, uart_id, baudrate=115200, **_kwargs):
        self.id = uart_id
        self.baudrate = baudrate
        self._rx = bytearray(UART_RX.pop(uart_id, b""))
        self.sent = bytearray()
        UARTS[uart_id] = self

    def feed(self, data):
        """Test hook: bytes arriving on RX."""
        self._rx.extend(data)

    def any(self):
        return len(self._rx)

    def read(self, nbytes=None):
        if not self._rx:
            return None
        if nbytes is None or nbytes > len(self._rx):
            nbytes = len(self._rx)
        data = bytes(self._rx[:nbytes])
        self._rx = self._rx[nbytes:]
        return data

    def write(self, data):
        self.sent.extend(data)
        return len(data)


class SPI:
    def __init__(self, spi_id, baudrate=1000000, polarity=0, phase=0, **_kwargs):
        self.id = spi_id
        self.baudrate = baudrate
        self.device = None
        SPIS[spi_id] = self

    def attach(self, device):
        """Test hook: `device.transfer(tx: bytes) -> bytes` of the same length answers every transaction."""
        self.device = device

    def _transfer(self, tx):
        if self.device is None:
            return bytes(len(tx))       # nothing on the bus: MISO pulled low
        return self.device.transfer(bytes(tx))

    def write(self, buf):
        self._transfer(buf)

    def write_readinto(self, tx, rx):
        answer = self._transfer(tx)
        for i in range(len(rx)):
            rx[i] = answer[i]


class WDT:
    def __init__(self, id=0, timeout=5000):
        self.timeout = timeout
        self.feeds = 0
        WDTS.append(self)

    def feed(self):
        self.feeds += 1


def unique_id():
    return b"\x12\x34\x56\x78"


def reset():
    RESETS.append(1)
    raise SystemExit("machine.reset()")

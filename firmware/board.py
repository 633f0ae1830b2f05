"""NodeMCU v1.0 (ESP-12E, ESP8266) pin plan: the one place pin numbers live. See docs/wiring.md.

HSPI is fixed in silicon to GPIO14 (SCK), GPIO12 (MISO), GPIO13 (MOSI), so the MFRC522 takes D5/D6/D7 and its chip
select D8; the encoder moves off D5 to D4 (GPIO2: it has the IRQ and the pull-up an open-collector sensor needs).
The ESP8266's only receiving UART is UART0, shared with the USB REPL: the IPS receiver gets it after boot, when
the REPL is detached (train.py). Holding the FLASH button (D3, GPIO0) while the firmware starts keeps the REPL
and skips the train loop: press it just after releasing RESET (held during the reset itself, GPIO0 low selects the
ROM's serial bootloader instead). The firmware also keeps the REPL for a grace period after boot, which is how
`cbtc flash` reaches a board whose UART0 belongs to the IPS.
Nothing runs at import: the boot (startup.py) calls make_drivers() once.
"""

import gc

try:
    from micropython import const
except ImportError:  # CPython
    def const(value):
        return value

# D4: encoder output (open collector, on-board pull-up); a strapping pin, so it must be high at boot
_ENCODER_A = const(2)
_ENCODER_B = const(16)        # D0: the encoder's second channel, read at A's edges (GPIO16 has no IRQ, none needed)
_MOTOR_IN1 = const(5)         # D1  H-bridge IN1 (forward PWM)
_MOTOR_IN2 = const(4)         # D2  H-bridge IN2 (reverse PWM)
_MOTOR_PWM_HZ = const(1000)   # PWM frequency (Hz)
_RFID_SPI = const(1)          # HSPI: SCK GPIO14 (D5), MISO GPIO12 (D6), MOSI GPIO13 (D7)
_RFID_SPI_HZ = const(1000000)
_RFID_CS = const(15)          # D8  chip select (the board's pull-down keeps GPIO15 low at boot, as it must be)
_IPS_UART = const(0)          # UART0 RX = GPIO3 (RX pin), after the REPL is detached
_IPS_BAUD = const(115200)     # set the hedgehog's UART speed to this in the Marvelmind dashboard
_MAINT_PIN = const(0)         # D3  FLASH button: held low as the firmware starts = maintenance, stay in the REPL
_INTEGRITY_PIN = const(1)     # TX  the train line: a wire loop through every coupling to the last car and back to
                              # GND, read once the REPL is detached (`integrity_loop` in train_config.py)


def make_drivers():
    """The board's drivers as a dict: encoder, ips, rfid, motor (motor braked), maint: the FLASH button's pin
    (reads 0 while held: maintenance, the board stays in the REPL), and integrity: the train line's pin number (UART0
    TX: made an input only once the REPL is detached)."""
    import machine

    gc.collect()
    from drivers.motor import Motor

    motor = Motor(machine.PWM(machine.Pin(_MOTOR_IN1), freq=_MOTOR_PWM_HZ, duty=0),
                  machine.PWM(machine.Pin(_MOTOR_IN2), freq=_MOTOR_PWM_HZ, duty=0))
    motor.brake()
    gc.collect()
    from drivers.encoder import Encoder

    # two channels: the board sees itself roll back or run backwards (roll-away and reverse-movement protection)
    encoder = Encoder(machine.Pin(_ENCODER_A, machine.Pin.IN, machine.Pin.PULL_UP),
                      machine.Pin(_ENCODER_B, machine.Pin.IN), quadrature=False)
    gc.collect()
    from drivers.mfrc522 import Mfrc522

    rfid = Mfrc522(machine.SPI(_RFID_SPI, baudrate=_RFID_SPI_HZ),   # mode 0: polarity 0, phase 0 (the defaults)
                   machine.Pin(_RFID_CS, machine.Pin.OUT, value=1), None)   # its RST tied to 3.3 V
    gc.collect()
    from drivers.ips import IpsReceiver

    ips = IpsReceiver(machine.UART(_IPS_UART, _IPS_BAUD, rxbuf=256))
    gc.collect()
    return {"encoder": encoder, "ips": ips, "rfid": rfid, "motor": motor,
            "maint": machine.Pin(_MAINT_PIN, machine.Pin.IN, machine.Pin.PULL_UP), "integrity": _INTEGRITY_PIN}

"""The board's parsers run on generated inputs, the same under CPython and the MicroPython unix port: each function
takes plain values (bytes, lists of ints) and returns a JSON-able outcome, so tests/test_properties.py compares the
two interpreters case by case. Hypothesis generates the cases on the CPython side; nothing here needs it."""

import json

import machine

import wire
from drivers.ips import IpsReceiver
from drivers.mfrc522 import Mfrc522
from fake_mfrc522 import FakeMfrc522

KEY = b"0123456789abcdef"


def command_outcome(payload):
    """["ok", sorted [name, value] pairs] or ["refused", reason] of a payload on train A's command topic."""
    try:
        msg = wire.decode_command(KEY, "cbtc/train/A/cmd", payload)
    except wire.WireError as exc:
        return ["refused", exc.reason]
    return ["ok", sorted([k, msg[k]] for k in msg)]


def ips_outcome(chunks):
    """The fixes (or None) of one poll after each chunk of bytes arrives on the IPS UART, and the counters."""
    uart = machine.UART(1, 115200)
    ips = IpsReceiver(uart)
    fixes = []
    for i, chunk in enumerate(chunks):
        uart.buf.extend(chunk)
        fix = ips.poll(10 * i)
        fixes.append(None if fix is None else list(fix))
    return [fixes, ips.frames_ok, ips.crc_errors, ips.other_frames]


class RandomChip:
    """An SPI bus whose chip answers every register read with the next of `answers` (cycled); -1 raises OSError."""

    def __init__(self, answers):
        self.answers = answers or [0]
        self.i = 0

    def _next(self):
        value = self.answers[self.i % len(self.answers)]
        self.i += 1
        if value < 0:
            raise OSError(5)
        return value

    def write(self, tx):
        pass

    def write_readinto(self, tx, rx):
        rx[1] = self._next()


def mfrc522_outcome(answers, polls):
    """present, then each poll's uid (every 60 ms) and data, of a reader whose chip answers `answers`."""
    cs = machine.Pin(15, machine.Pin.OUT, value=1)
    rst = machine.Pin(16, machine.Pin.OUT, value=0)
    try:
        reader = Mfrc522(RandomChip(answers), cs, rst)
    except OSError:
        return ["no reader"]
    out = [reader.present]
    for k in range(polls):
        try:
            out.append([reader.poll(60 * k), reader.data])
        except OSError:
            out.append("bus error")
    return out


def card_outcome(uid, sak, memory, corrupt):
    """What a reader reads of a (fake) card with this uid, SAK and memory, the BCC or the READ corrupted or not."""
    cs = machine.Pin(15, machine.Pin.OUT, value=1)
    rst = machine.Pin(16, machine.Pin.OUT, value=0)
    chip = FakeMfrc522(cs)
    reader = Mfrc522(chip, cs, rst)
    chip.uid, chip.sak, chip.memory = uid, sak, bytearray(memory)
    chip.corrupt_bcc, chip.corrupt_read = corrupt & 1 == 1, corrupt & 2 == 2
    return [reader.read_uid(), reader.data]


def run(kind, cases):
    """Print one JSON outcome per case, for the unix-port side of the comparison."""
    for case in cases:
        if kind == "command":
            result = command_outcome(case)
        elif kind == "ips":
            result = ips_outcome(case)
        elif kind == "card":
            result = card_outcome(*case)
        else:
            result = mfrc522_outcome(case[0], case[1])
        print(json.dumps(result))

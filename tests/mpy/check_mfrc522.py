"""MFRC522 checks that run unchanged under CPython and under the MicroPython unix port.

Each `check_*` function builds the driver on the host shims (cbtc/board/host) and asserts byte-exact behaviour;
tests/test_drivers.py calls each one directly and again inside `micropython -X heapsize=36K`.
The chip is the register-level fake in tests/mpy/fake_mfrc522.py.
"""

import machine

from drivers.mfrc522 import Mfrc522, crc_a
from fake_mfrc522 import FakeMfrc522


def _reader(version=0x92, absent=None):
    cs = machine.Pin(15, machine.Pin.OUT, value=1)
    rst = machine.Pin(16, machine.Pin.OUT, value=0)
    chip = FakeMfrc522(cs, version)      # the chip also plays the SPI bus it sits on
    chip.absent_value = absent
    return chip, Mfrc522(chip, cs, rst), cs, rst


def check_mfrc522_present_and_uid():
    chip, reader, cs, rst = _reader()
    assert reader.present and reader.version == 0x92
    assert chip.resets == 1 and chip.bad_addresses == 0
    assert chip.regs[0x14] & 0x03 == 0x03                # antenna on
    assert cs.value() == 1 and rst.value() == 1          # deselected, out of reset
    assert reader.read_uid() is None                     # no card
    chip.uid = bytes([0xDE, 0xAD, 0xBE, 0xEF])
    assert reader.read_uid() == "DEADBEEF"
    chip.corrupt_bcc = True
    assert reader.read_uid() is None                     # BCC mismatch is not a read


def check_mfrc522_clone_versions():
    for version in (0x91, 0x88, 0x12):
        assert _reader(version)[1].present
    assert not _reader(0x55)[1].present


def check_mfrc522_absent_reader():
    for value in (0x00, 0xFF):
        chip, reader, cs, rst = _reader(absent=value)
        assert not reader.present
        assert reader.read_uid() is None
        assert reader.poll(0) is None and reader.poll(1000) is None


def check_mfrc522_bus_error_means_absent():
    class DeadBus:
        def write(self, buf):
            raise OSError(19)

        def write_readinto(self, tx, rx):
            raise OSError(19)

    cs = machine.Pin(15, machine.Pin.OUT, value=1)
    reader = Mfrc522(DeadBus(), cs, machine.Pin(16, machine.Pin.OUT))
    assert not reader.present and reader.poll(0) is None
    assert cs.value() == 1                               # chip select released after the failed transfer


def check_mfrc522_once_per_passage():
    chip, reader, cs, rst = _reader()
    chip.uid = bytes([0x04, 0xA1, 0x00, 0x00])
    seen = []
    for t_ms in range(0, 1000, 10):                      # loop at 100 Hz; the tag is under the reader 0-200 ms
        if t_ms == 200:
            chip.uid = None
        if t_ms == 400:                                   # back after 200 ms: the same passage (too short an absence)
            chip.uid = bytes([0x04, 0xA1, 0x00, 0x00])
        if t_ms == 450:
            chip.uid = None
        if t_ms == 800:                                   # back after 350 ms: a new passage
            chip.uid = bytes([0x04, 0xA1, 0x00, 0x00])
        uid = reader.poll(t_ms)
        if uid is not None:
            seen.append((t_ms, uid))
    assert seen == [(0, "04A10000"), (800, "04A10000")], seen


def check_mfrc522_other_tag_reported_at_once():
    chip, reader, cs, rst = _reader()
    chip.uid = bytes([1, 2, 3, 4])
    assert reader.poll(0) == "01020304"
    chip.uid = bytes([5, 6, 7, 8])
    assert reader.poll(20) == "05060708"                 # every poll reads: the loop sets the pace
    assert reader.poll(40) is None                       # the same tag, still there: one report a passage


def check_mfrc522_crc_a():
    assert crc_a(bytes((0x30, 0x00))) == 0xA802          # READ page 0 is sent as 30 00 02 A8
    assert crc_a(b"") == 0x6363


def check_mfrc522_seven_byte_uid_and_balise_pages():
    chip, reader, cs, rst = _reader()
    chip.uid = bytes([0x04, 0x5A, 0x21, 0x8A, 0x6B, 0x51, 0x80])    # an NTAG213
    image = bytes(range(0xA0, 0xB0))
    chip.memory[16:32] = image                                     # pages 4-7: the balise telegram
    assert reader.read_uid() == "045A218A6B5180"
    assert reader.data == "a0a1a2a3a4a5a6a7a8a9aaabacadaeaf"
    chip.corrupt_read = True                                       # a bit lost on the air: the CRC says so
    assert reader.read_uid() == "045A218A6B5180" and reader.data is None
    chip.uid = None
    assert reader.read_uid() is None and reader.data is None


def check_mfrc522_classic_card_has_no_balise_data():
    chip, reader, cs, rst = _reader()
    chip.uid = bytes([0xDE, 0xAD, 0xBE, 0xEF])
    chip.sak = 0x08                                                # MIFARE Classic 1K: no READ without a key
    assert reader.read_uid() == "DEADBEEF" and reader.data is None


def check_mfrc522_ten_byte_uid_reads_whole_or_not_at_all():
    chip, reader, _cs, _rst = _reader()
    chip.uid = bytes(range(0x10, 0x1A))                  # three cascade levels
    assert reader.read_uid() == "10111213141516171819"
    chip.sak = 0x04                                      # the last level still claims more: incomplete, not a read
    assert reader.read_uid() is None

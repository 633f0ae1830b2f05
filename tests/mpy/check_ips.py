"""IPS receiver checks that run unchanged under CPython and under the MicroPython unix port.

Each `check_*` function builds the driver on the host shims (cbtc/board/host) and asserts byte-exact behaviour;
tests/test_drivers.py calls each one directly and again inside `micropython -X heapsize=36K`.
Frames are built here with a table-driven CRC-16/Modbus, independent of the driver's bitwise one.
"""

import struct

import machine

from drivers.ips import IpsReceiver, crc16_modbus


def _crc_table():
    table = []
    for byte in range(256):
        crc = byte
        for _ in range(8):
            crc = (crc >> 1) ^ 0xA001 if crc & 1 else crc >> 1
        table.append(crc)
    return table


_TABLE = _crc_table()


def modbus_crc(data):
    crc = 0xFFFF
    for byte in data:
        crc = (crc >> 8) ^ _TABLE[(crc ^ byte) & 0xFF]
    return crc


def frame(code, payload):
    body = bytes([0xFF, 0x47, code & 0xFF, code >> 8, len(payload)]) + payload
    return body + struct.pack("<H", modbus_crc(body))


def position(x_mm, y_mm, z_mm, flags=0, ts=123456):
    return frame(0x0011, struct.pack("<IiiiBBhH", ts, x_mm, y_mm, z_mm, flags, 7, 900, 0))


def feed(uart, data):
    """Bytes arriving on the shim UART's RX."""
    uart.buf.extend(data)


def _ips():
    uart = machine.UART(1, 115200)
    return uart, IpsReceiver(uart)


def check_crc_vector():
    assert modbus_crc(b"123456789") == 0x4B37
    assert crc16_modbus(b"123456789", 0, 9) == 0x4B37
    # a Marvelmind position frame header + payload: both implementations agree
    raw = position(1, 2, 3)
    assert crc16_modbus(raw, 0, len(raw) - 2) == modbus_crc(raw[:-2])


def check_ips_one_frame():
    uart, ips = _ips()
    raw = position(1500, -250, 80, flags=0x02)
    assert len(raw) == 5 + 22 + 2
    feed(uart, raw)
    assert ips.poll(1000) == (1000, 1500, -250, 80, 0x02)
    assert ips.frames_ok == 1 and ips.crc_errors == 0 and ips.garbage_bytes == 0
    assert ips.last_fix_ms == 1000
    assert ips.poll(1010) is None and uart.any() == 0


def check_ips_split_byte_by_byte():
    uart, ips = _ips()
    raw = position(-7, 8, 9)
    for i, byte in enumerate(raw):
        feed(uart, bytes([byte]))
        fix = ips.poll(2000 + i)
        if i < len(raw) - 1:
            assert fix is None, i
    assert fix == (2000 + len(raw) - 1, -7, 8, 9, 0)
    assert ips.frames_ok == 1 and ips.garbage_bytes == 0


def check_ips_resync_after_garbage():
    uart, ips = _ips()
    junk = bytes([0x13, 0x37, 0x47, 0x00, 0x99, 0xFE])
    lone = bytes([0xFF])                                  # a sync byte not followed by 0x47
    fake = bytes([0xFF, 0x47, 0x11, 0x00, 0xF0])          # a header with an absurd length
    feed(uart, junk + lone + fake + position(10, 20, 30))
    assert ips.poll(50) == (50, 10, 20, 30, 0)
    assert ips.frames_ok == 1 and ips.crc_errors == 0
    assert ips.garbage_bytes == len(junk) + len(lone) + len(fake)
    # random bytes between two frames
    seed = 12345
    noise = bytearray()
    for _ in range(200):
        seed = (seed * 1103515245 + 12345) & 0x7FFFFFFF
        noise.append((seed >> 16) & 0xFF)
    feed(uart, bytes(noise) + position(11, 21, 31))
    fix = None
    for t in range(60, 70):                              # more than one chunk of UART data
        fix = ips.poll(t) or fix
    assert fix is not None and fix[1:4] == (11, 21, 31)
    assert ips.frames_ok == 2


def check_ips_bad_crc_rejected():
    uart, ips = _ips()
    bad = bytearray(position(1, 2, 3))
    bad[10] ^= 0x40                                      # a flipped bit in x
    feed(uart, bytes(bad) + position(4, 5, 6))
    assert ips.poll(7) == (7, 4, 5, 6, 0)
    assert ips.crc_errors == 1 and ips.frames_ok == 1


def check_ips_other_code_and_newest_wins():
    uart, ips = _ips()
    feed(uart, frame(0x0003, bytes(range(16))) + position(1, 1, 1) + position(2, 2, 2))
    assert ips.poll(9) == (9, 2, 2, 2, 0)
    assert ips.other_frames == 1 and ips.frames_ok == 2


def check_ips_false_header_never_holds_a_real_frame_back():
    for claimed in (22, 40, 64):                         # FF 47 inside other data, claiming a length up to 64
        uart, ips = _ips()
        false = bytes([0xFF, 0x47, 0x03, 0x00, claimed])
        feed(uart, false + position(12, 34, 56))
        assert ips.poll(100) == (100, 12, 34, 56, 0), claimed   # in the same poll, not after the claim has arrived
        assert ips.garbage_bytes == len(false) and ips.frames_ok == 1
        feed(uart, position(13, 35, 57))                 # and the next one as usual
        assert ips.poll(110) == (110, 13, 35, 57, 0)
    uart, ips = _ips()                                   # a real frame still arriving is waited for, not skipped
    raw = position(7, 8, 9)
    feed(uart, raw[:20])
    assert ips.poll(200) is None and ips.garbage_bytes == 0
    feed(uart, raw[20:])
    assert ips.poll(210) == (210, 7, 8, 9, 0)

"""Marvelmind-style indoor GPS receiver ("hedgehog") on a UART.

IpsReceiver(uart) takes a ready `machine.UART`. Frame on the wire:

    0xFF 0x47 | data code (u16 LE) | payload length (u8) | payload | CRC-16/Modbus (u16 LE) over header + payload

Data code 0x0011 is a position in millimetres, 22 payload bytes: u32 timestamp, i32 x, i32 y, i32 z, u8 flags,
u8 address, i16 angle, 2 reserved. `poll(now_ms)` reads only what `uart.any()` says is waiting (it never blocks),
parses every complete frame and returns the newest position fix as (t_ms, x_mm, y_mm, z_mm, flags), stamped with
`now_ms` (the board's monotonic ms when the frame was read), or None. A bad header, an absurd length or a bad CRC
never stalls the parser: it drops one byte and looks for the next header; a header whose claimed length has not
arrived yet never holds back a whole good frame behind it.
"""

import struct

try:
    from micropython import const
except ImportError:  # CPython
    def const(value):
        return value

_SYNC = const(0xFF)           # first header byte
_TYPE = const(0x47)           # second header byte: "data from the hedgehog"
_CODE_POS_MM = const(0x0011)  # position, mm resolution
_POS_LEN = const(22)          # payload bytes of a position frame
_HEADER = const(5)            # sync, type, code lo, code hi, length
_MAX_PAYLOAD = const(64)      # longest payload we accept; longer is a false header
_BUF = const(160)             # receive buffer: two longest frames and some
_CHUNK = const(64)            # most bytes taken from the UART per read


def crc16_modbus(buf, start, end):
    """CRC-16/Modbus (init 0xFFFF, reflected poly 0xA001) of buf[start:end]."""
    crc = 0xFFFF
    for i in range(start, end):
        crc ^= buf[i]
        for _ in range(8):
            if crc & 1:
                crc = (crc >> 1) ^ 0xA001
            else:
                crc >>= 1
    return crc


class IpsReceiver:
    def __init__(self, uart):
        self.uart = uart
        self.buf = bytearray(_BUF)
        self._len = 0
        self.frames_ok = 0       # valid position frames
        self.crc_errors = 0      # frames with a good header but a wrong CRC
        self.garbage_bytes = 0   # bytes skipped while looking for a header
        self.other_frames = 0    # valid frames of other data codes (ignored)
        self.last_fix_ms = None  # board ms of the newest fix, None until the first

    def poll(self, now_ms):
        """Read what is waiting and parse it; the newest fix since the last poll or None (see module doc)."""
        fix = None
        waiting = self.uart.any()
        while waiting > 0:
            room = _BUF - self._len
            data = self.uart.read(min(waiting, room, _CHUNK))
            if not data:
                break
            self.buf[self._len:self._len + len(data)] = data
            self._len += len(data)
            waiting -= len(data)
            newest = self._parse(now_ms)
            if newest is not None:
                fix = newest
        if fix is not None:
            self.last_fix_ms = now_ms
        return fix

    def _frame_end(self, i, n):
        """At buf[i]: the index just past a whole frame with a good CRC there; 0 if the bytes held so far could
        still be the start of one (wait for more); -1 if it is no frame; -2 if its CRC is wrong."""
        buf = self.buf
        if buf[i] != _SYNC:
            return -1
        if n - i < 2:
            return 0
        if buf[i + 1] != _TYPE:
            return -1
        if n - i < _HEADER:
            return 0
        code = buf[i + 2] | (buf[i + 3] << 8)
        length = buf[i + 4]
        if length > _MAX_PAYLOAD or (code == _CODE_POS_MM and length != _POS_LEN):
            return -1
        end = i + _HEADER + length
        if n - end < 2:
            return 0
        if crc16_modbus(buf, i, end) != buf[end] | (buf[end + 1] << 8):
            return -2
        return end + 2

    def _parse(self, now_ms):
        buf = self.buf
        n = self._len
        i = 0
        fix = None
        while i < n:
            end = self._frame_end(i, n)
            if end == 0:
                # incomplete; but a whole good frame further on proves this header false (FF 47 inside other data
                # claiming a length): skip to it rather than hold it back until the claimed length has arrived
                j = i + 1
                while j < n and self._frame_end(j, n) <= 0:
                    j += 1
                if j == n:
                    break
                self.garbage_bytes += j - i
                i = j
                continue
            if end < 0:
                if end == -2:
                    self.crc_errors += 1
                self.garbage_bytes += 1
                i += 1
                continue
            code = buf[i + 2] | (buf[i + 3] << 8)
            if code == _CODE_POS_MM:
                _ts, x_mm, y_mm, z_mm, flags = struct.unpack_from("<IiiiB", buf, i + _HEADER)
                fix = (now_ms, x_mm, y_mm, z_mm, flags)
                self.frames_ok += 1
            else:
                self.other_frames += 1
            i = end
        if i:
            buf[0:n - i] = buf[i:n]
            self._len = n - i
        return fix

"""The IPS modem on the controller's machine: every beacon's position fixes on a serial port, those of a train's tail
beacon handed to the zone (ZoneController.on_tail_fix), which checks the train's configured length with them.

The frames are the hedgehog's (firmware/drivers/ips.py parses them, the same code as on a board); a modem sends
each beacon's fixes with its address. `IpsModem.poll` reads what is waiting, never blocks, and is run every
POLL_S by the live loop.
"""

import struct

from cbtc.errors import ConfigError
from cbtc.firmware.drivers.ips import _CODE_POS_MM, _HEADER, IpsReceiver

POLL_S = 0.01      # how often the port is read: well within the beacons' period (16 Hz at most)
BAUD = 115200      # the modem's USB serial rate


class _BeaconFixes(IpsReceiver):
    """The hedgehog parser keeping every fix with its beacon's address, not only the newest. Its loop is the board's
    (`IpsReceiver._parse`) written again: a hook for the address in the board's parser costs 320 B of the board's
    heap (tests/test_heap32.py, loop peak), and the board has none to spare."""

    def __init__(self, uart):
        super().__init__(uart)
        self.fixes = []   # (address, x_mm, y_mm) parsed since the caller last emptied it

    def _parse(self, now_ms):
        buf, n, i, fix = self.buf, self._len, 0, None
        while i < n:
            end = self._frame_end(i, n)
            if end == 0:   # incomplete: skip to a whole good frame further on, or wait for more
                j = i + 1
                while j < n and self._frame_end(j, n) <= 0:
                    j += 1
                if j == n:
                    break
                self.garbage_bytes += j - i
                i = j
                continue
            if end < 0:
                self.crc_errors += end == -2
                self.garbage_bytes += 1
                i += 1
                continue
            if buf[i + 2] | (buf[i + 3] << 8) == _CODE_POS_MM:
                _ts, x_mm, y_mm, z_mm, flags, address = struct.unpack_from("<IiiiBB", buf, i + _HEADER)
                self.fixes.append((address, x_mm, y_mm))
                fix = (now_ms, x_mm, y_mm, z_mm, flags)
                self.frames_ok += 1
            else:
                self.other_frames += 1
            i = end
        if i:
            buf[0:n - i] = buf[i:n]
            self._len = n - i
        return fix


class _SerialUart:
    """A pyserial port with the two calls the parser makes of a board's UART."""

    def __init__(self, port):
        self.port = port

    def any(self):
        return self.port.in_waiting

    def read(self, n):
        return self.port.read(n)


def parse_tail_beacons(text: str) -> dict:
    """`A=5,B=6` (train id = beacon address 1-254) as {address: train id}; ConfigError naming the bad part."""
    beacons = {}
    for part in filter(None, (p.strip() for p in text.split(","))):
        train_id, eq, address = part.partition("=")
        if not eq or not train_id or not address.isdigit() or not 1 <= int(address) <= 254:
            raise ConfigError(f"{part!r} is not TRAIN=ADDRESS with an address 1-254 (the beacon's "
                              f"address in the Marvelmind dashboard), e.g. A=5,B=6")
        if int(address) in beacons:
            raise ConfigError(f"address {address} is given to two trains; each beacon has its own")
        beacons[int(address)] = train_id
    if not beacons:
        raise ConfigError("no beacon given; give TRAIN=ADDRESS,... e.g. A=5,B=6")
    return beacons


class IpsModem:
    def __init__(self, port, beacons: dict, zone, now_fn, latency_s: float):
        self._port = port                  # an open pyserial port (timeout 0), or any object with in_waiting/read
        self._parser = _BeaconFixes(_SerialUart(port))
        self.beacons = beacons             # beacon address -> train id, for the tail beacons only
        self.zone = zone
        self.now_fn = now_fn
        self.latency_s = latency_s         # from the beacon's sample to its fix on the port
        self.fixes_taken = 0
        self.other_beacons = 0             # fixes of beacons that are not a tail beacon (the trains' own hedgehogs)

    @classmethod
    def open(cls, path: str, beacons: dict, zone, now_fn, latency_s: float):
        """The modem on serial port `path`; ConfigError naming the port and the fix when it cannot be opened."""
        import serial
        try:
            port = serial.Serial(path, BAUD, timeout=0)
        except (serial.SerialException, OSError, ValueError) as exc:
            raise ConfigError(f"--ips-modem {path}: cannot open the port ({exc}); plug the modem in and give its "
                              f"port (e.g. /dev/ttyACM0), or leave --ips-modem out") from None
        return cls(port, beacons, zone, now_fn, latency_s)

    def poll(self, now_s: float = None) -> None:
        """Read the port and hand every tail beacon's fix to the zone, stamped a latency before it was read."""
        parser = self._parser
        try:
            parser.poll(0)
        except OSError:   # the modem unplugged: its beacons fall silent, which the zone treats as it must
            return
        if not parser.fixes:
            return
        t_s = (self.now_fn() if now_s is None else now_s) - self.latency_s
        for address, x_mm, y_mm in parser.fixes:
            train_id = self.beacons.get(address)
            if train_id is None:
                self.other_beacons += 1
                continue
            self.fixes_taken += 1
            self.zone.on_tail_fix(train_id, t_s, x_mm, y_mm)
        parser.fixes.clear()

    def close(self) -> None:
        self._port.close()

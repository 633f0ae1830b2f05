"""The IPS modem on the controller's machine, read over a real pseudo-terminal: each tail beacon's fixes reach the
zone, the trains' own hedgehogs and line noise do not, and `cbtc zone` refuses a bad port or beacon list at once."""

import os
import pty
import struct
import time

import pytest

from cbtc.cli import main
from cbtc.errors import ConfigError
from cbtc.firmware.drivers.ips import crc16_modbus
from cbtc.live.ips_modem import IpsModem, parse_tail_beacons


def frame(address, x_mm, y_mm):
    body = bytes([0xFF, 0x47, 0x11, 0x00, 22]) + struct.pack("<IiiiBBhH", 0, x_mm, y_mm, 0, 0, address, 0, 0)
    return body + struct.pack("<H", crc16_modbus(body, 0, len(body)))


class Zone:
    def __init__(self):
        self.fixes = []

    def on_tail_fix(self, train_id, t_s, x_mm, y_mm):
        self.fixes.append((train_id, t_s, x_mm, y_mm))


@pytest.fixture
def port():
    master, slave = pty.openpty()
    yield master, os.ttyname(slave)
    os.close(master)
    os.close(slave)


def test_each_tail_beacon_s_fixes_reach_the_zone_stamped_a_latency_before_they_were_read(port):
    master, path = port
    zone = Zone()
    modem = IpsModem.open(path, parse_tail_beacons("A=5,B=6"), zone, lambda: 10.0, 0.06)
    try:
        os.write(master, b"\x00\xff\x47junk" + frame(5, 1200, -340) + frame(9, 1, 2) + frame(6, 5, 6)[:10])
        for _ in range(200):   # the pty hands the bytes on when the kernel gets to it: a loaded machine waits
            modem.poll()
            if zone.fixes:
                break
            time.sleep(0.01)
        assert zone.fixes == [("A", pytest.approx(9.94), 1200, -340)] and modem.other_beacons == 1
        os.write(master, frame(6, 5, 6)[10:] + frame(6, 7, 8))   # the rest of a frame cut in two, then one more
        for _ in range(200):
            modem.poll(11.0)
            if len(zone.fixes) == 3:
                break
            time.sleep(0.01)
        assert zone.fixes[1:] == [("B", pytest.approx(10.94), 5, 6), ("B", pytest.approx(10.94), 7, 8)]
        assert modem.fixes_taken == 3
    finally:
        modem.close()


@pytest.mark.parametrize("text,named", [("A=0", "address 1-254"), ("A5", "TRAIN=ADDRESS"),
                                        ("A=5,B=5", "address 5 is given to two trains"), (",", "no beacon")])
def test_a_bad_beacon_list_is_named(text, named):
    with pytest.raises(ConfigError, match=named):
        parse_tail_beacons(text)


def test_a_port_that_cannot_be_opened_is_named_with_the_fix():
    with pytest.raises(ConfigError, match="--ips-modem /nonexistent/tty: cannot open the port"):
        IpsModem.open("/nonexistent/tty", {5: "A"}, Zone(), lambda: 0.0, 0.06)


@pytest.mark.parametrize("extra,named", [
    (["--ips-modem", "/dev/null"], "--ips-modem and --tail-beacons go together"),
    (["--ips-modem", "/nonexistent/tty", "--tail-beacons", "Z=5"], "train Z is not in this zone"),
    (["--ips-modem", "/nonexistent/tty", "--tail-beacons", "A=5"], "cannot open the port"),
])
def test_cbtc_zone_refuses_a_bad_modem_before_it_connects(capsys, extra, named):
    argv = ["zone", "--broker", "mqtt://127.0.0.1:1", "--layout", "itb_square", "--train-ids", "A,B"] + extra
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert named in err and "Traceback" not in err and err.count("\n") == 1, err

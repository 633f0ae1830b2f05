"""Hamming-coded telegrams: every 1-bit error corrected, every 2-bit error detected, payload profiles, MicroPython."""

import os
import random
import shutil
import subprocess

import pytest

from cbtc.firmware.manifest import FIRMWARE_DIR
from cbtc.protocol import telegram

BALISE = telegram.balise_payload(0x04A7, 1234567, 0x05)


def test_frame_layout_and_clean_decode():
    frame = telegram.encode(BALISE)
    # 13 sync + 6 bytes * 16 + CRC 16 + parity 1, as docs/source_systems.md says
    assert len(frame) == telegram.frame_bits(6) == 126
    assert tuple(frame[:13]) == telegram.SYNC
    assert telegram.decode(frame) == (BALISE, "ok")
    assert telegram.parse_balise_payload(BALISE) == (0x04A7, 1234567, 5)


def test_hamming84_corrects_each_single_error_of_every_nibble():
    for nibble in range(16):
        word = telegram.hamming84_encode(nibble)
        assert telegram.hamming84_decode(word) == (nibble, 0)
        for i in range(8):
            bad = list(word)
            bad[i] ^= 1
            assert telegram.hamming84_decode(bad) == (nibble, 1)


def test_every_one_bit_error_is_corrected():
    frame = telegram.encode(BALISE)
    for i in range(len(frame)):
        bad = bytearray(frame)
        bad[i] ^= 1
        assert telegram.decode(bad) == (BALISE, "corrected"), i


def test_every_two_bit_error_is_detected():
    frame = telegram.encode(BALISE)
    n = len(frame)
    results = set()
    for i in range(n):
        for j in range(i + 1, n):
            bad = bytearray(frame)
            bad[i] ^= 1
            bad[j] ^= 1
            results.add(telegram.decode(bad))
    assert results == {(None, "detected")}  # all 126 * 125 / 2 = 7875 patterns


def test_speed_code_payload_round_trip_and_range_checks():
    data = telegram.speed_code_payload(17, 6)
    assert telegram.decode(telegram.encode(data)) == (data, "ok")
    assert telegram.parse_speed_code_payload(data) == (17, 6)
    with pytest.raises(ValueError):
        telegram.speed_code_payload(3, 8)
    with pytest.raises(ValueError):
        telegram.balise_payload(1, 2 ** 24, 0)


def test_crc8_check_value():
    # CRC-8 (poly 0x07, init 0) of "123456789" is 0xF4 (the catalogue's check value)
    assert telegram.crc8(b"123456789") == 0xF4


@pytest.mark.skipif(shutil.which("micropython") is None, reason="MicroPython unix port not installed")
def test_decoder_under_micropython():
    rnd = random.Random(3)
    frame = telegram.encode(BALISE)
    singles = rnd.sample(range(len(frame)), 20)
    pairs = [tuple(sorted(rnd.sample(range(len(frame)), 2))) for _ in range(20)]
    script = "\n".join([
        "import telegram",
        "p = telegram.balise_payload(0x04A7, 1234567, 5)",
        "f = telegram.encode(p)",
        "assert telegram.decode(f) == (p, 'ok')",
        "for i in %r:" % (singles,),
        "    b = bytearray(f); b[i] ^= 1",
        "    assert telegram.decode(b) == (p, 'corrected'), i",
        "for i, j in %r:" % (pairs,),
        "    b = bytearray(f); b[i] ^= 1; b[j] ^= 1",
        "    assert telegram.decode(b) == (None, 'detected'), (i, j)",
        "assert telegram.parse_speed_code_payload(telegram.speed_code_payload(9, 7)) == (9, 7)",
        "print('OK')",
    ])
    env = dict(os.environ, MICROPYPATH=FIRMWARE_DIR + ":.frozen")
    out = subprocess.run(["micropython", "-c", script], env=env, capture_output=True, text=True, timeout=30)
    assert out.stdout.strip() == "OK", out.stderr

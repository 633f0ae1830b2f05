"""Balise and speed-code telegrams: sync + Hamming-coded data blocks + error-control bits + final parity (Hill, 1990).

MicroPython-compatible (ints and bytearrays only); the controller imports the same file. A telegram is a bytearray
of bits (one 0/1 per element), in transmission order:

  13 bits          sync: Barker-13 1111100110101
  16 bits per byte data: each data byte as two nibbles (high first), each nibble an extended Hamming (8,4) codeword
                   (SECDED); the bytes form three blocks as the payload profiles lay them out
  16 bits          error control: CRC-8 (polynomial 0x07, init 0x00) over the data bytes, Hamming (8,4) coded
  1 bit            final parity: even parity over everything after the sync

Hamming (8,4) codeword order: p1 p2 d1 p3 d2 d3 d4 p0 (positions 1..7 of Hamming(7,4), then the overall parity).

decode() corrects at most one bit error per telegram and rejects anything that shows more: every 1-bit error is
corrected, every 2-bit error is detected; 3 or more errors are caught by the CRC and the cross-checks except with
small probability.

Payload profiles:
  balise      6 bytes: tag id u16, position along the track s_mm u24, flags u8; the 126-bit telegram is stored
              packed (see pack) in the 16 data bytes of the tag, which the board reads after its UID
  speed code  3 bytes: block id u16, code index u8 (0..7)
"""

SYNC = (1, 1, 1, 1, 1, 0, 0, 1, 1, 0, 1, 0, 1)  # Barker-13
CRC_POLY = 0x07
SPEED_CODES = 8

OK = "ok"
CORRECTED = "corrected"
DETECTED = "detected"


def frame_bits(n_data_bytes):
    """Length in bits of the telegram of `n_data_bytes` data bytes."""
    return len(SYNC) + 16 * n_data_bytes + 16 + 1


def crc8(data):
    """CRC-8 with polynomial 0x07, init 0x00, no reflection, no final xor (check value of b"123456789": 0xF4)."""
    crc = 0
    for byte in data:
        crc ^= byte
        for _ in range(8):
            if crc & 0x80:
                crc = ((crc << 1) ^ CRC_POLY) & 0xFF
            else:
                crc = (crc << 1) & 0xFF
    return crc


def hamming84_encode(nibble):
    """The 8 bits (bytearray of 0/1) of the extended Hamming (8,4) codeword of `nibble` (0..15)."""
    d1 = (nibble >> 3) & 1
    d2 = (nibble >> 2) & 1
    d3 = (nibble >> 1) & 1
    d4 = nibble & 1
    p1 = d1 ^ d2 ^ d4
    p2 = d1 ^ d3 ^ d4
    p3 = d2 ^ d3 ^ d4
    word = bytearray((p1, p2, d1, p3, d2, d3, d4, 0))
    word[7] = sum(word) & 1
    return word


def hamming84_decode(word):
    """(nibble, flips) of an (8,4) codeword: flips 0 (clean) or 1 (one bit corrected); (None, -1) when two bits
    are wrong (uncorrectable)."""
    syndrome = 0
    for pos in range(1, 8):
        if word[pos - 1]:
            syndrome ^= pos
    odd = sum(word[:8]) & 1
    if not odd and syndrome:
        return None, -1
    bits = bytearray(word[:7])
    flips = 0
    if odd:
        flips = 1
        if syndrome:
            bits[syndrome - 1] ^= 1
    return (bits[2] << 3) | (bits[4] << 2) | (bits[5] << 1) | bits[6], flips


def _byte_bits(byte):
    out = hamming84_encode(byte >> 4)
    out.extend(hamming84_encode(byte & 0x0F))
    return out


def encode(data):
    """The telegram (bytearray of bits) carrying the data bytes `data`."""
    bits = bytearray(SYNC)
    for byte in data:
        bits.extend(_byte_bits(byte))
    bits.extend(_byte_bits(crc8(data)))
    bits.append(sum(bits[len(SYNC):]) & 1)
    return bits


def decode(frame):
    """(data, status) of a telegram: status 'ok' (bytes, no error), 'corrected' (bytes, exactly one bit was wrong
    and is fixed) or 'detected' (None: two or more errors, discard the telegram)."""
    n_bits = len(frame)
    n_data = (n_bits - len(SYNC) - 17) // 16
    if n_data < 1 or frame_bits(n_data) != n_bits:
        raise ValueError("telegram of %d bits: the length must be 13 + 16 * n_bytes + 17" % n_bits)
    sync_errors = 0
    for i in range(len(SYNC)):
        if frame[i] != SYNC[i]:
            sync_errors += 1
    flips = sync_errors
    values = bytearray(n_data + 1)
    pos = len(SYNC)
    for k in range(n_data + 1):
        hi, f_hi = hamming84_decode(frame[pos:pos + 8])
        lo, f_lo = hamming84_decode(frame[pos + 8:pos + 16])
        if f_hi < 0 or f_lo < 0:
            return None, DETECTED
        values[k] = (hi << 4) | lo
        flips += f_hi + f_lo
        pos += 16
    data = bytes(values[:n_data])
    parity_odd = sum(frame[len(SYNC):]) & 1
    if values[n_data] != crc8(data) or flips > 1:
        return None, DETECTED
    if flips == 0:
        if parity_odd:
            return data, CORRECTED  # the final parity bit itself
        return data, OK
    if sync_errors:  # one sync bit wrong: the rest must be clean
        if parity_odd:
            return None, DETECTED
        return data, CORRECTED
    if not parity_odd:  # one corrected bit must leave the overall parity odd
        return None, DETECTED
    return data, CORRECTED


def pack(frame):
    """The bits of `frame` packed into bytes, first bit in the most significant bit, the last byte padded with 0:
    how a balise telegram (126 bits) sits in the 16 data bytes of an NTAG/Ultralight tag (pages 4-7)."""
    out = bytearray((len(frame) + 7) // 8)
    for i in range(len(frame)):
        if frame[i]:
            out[i >> 3] |= 0x80 >> (i & 7)
    return bytes(out)


def unpack(data, n_bits):
    """The first `n_bits` bits of the bytes `data` (see pack), as a bytearray of 0/1."""
    if len(data) * 8 < n_bits:
        raise ValueError("%d bytes hold fewer than %d bits" % (len(data), n_bits))
    bits = bytearray(n_bits)
    for i in range(n_bits):
        bits[i] = (data[i >> 3] >> (7 - (i & 7))) & 1
    return bits


def balise_payload(tag_id, s_mm, flags):
    """6 data bytes of a balise telegram: tag id (0..65535), position along the track in mm (0..2^24-1), flags (u8)."""
    if not 0 <= tag_id <= 0xFFFF:
        raise ValueError("balise tag_id %d out of 0..65535" % tag_id)
    if not 0 <= s_mm <= 0xFFFFFF:
        raise ValueError("balise s_mm %d out of 0..16777215" % s_mm)
    if not 0 <= flags <= 0xFF:
        raise ValueError("balise flags %d out of 0..255" % flags)
    return bytes((tag_id >> 8, tag_id & 0xFF, s_mm >> 16, (s_mm >> 8) & 0xFF, s_mm & 0xFF, flags))


def parse_balise_payload(data):
    """(tag_id, s_mm, flags) of 6 balise data bytes."""
    if len(data) != 6:
        raise ValueError("balise payload must be 6 bytes, got %d" % len(data))
    return (data[0] << 8) | data[1], (data[2] << 16) | (data[3] << 8) | data[4], data[5]


def speed_code_payload(block_id, code_index):
    """3 data bytes of a fixed-block speed code: block id (0..65535) and code index (0..7)."""
    if not 0 <= block_id <= 0xFFFF:
        raise ValueError("speed code block_id %d out of 0..65535" % block_id)
    if not 0 <= code_index < SPEED_CODES:
        raise ValueError("speed code index %d out of 0..%d" % (code_index, SPEED_CODES - 1))
    return bytes((block_id >> 8, block_id & 0xFF, code_index))


def parse_speed_code_payload(data):
    """(block_id, code_index) of 3 speed-code data bytes."""
    if len(data) != 3 or data[2] >= SPEED_CODES:
        raise ValueError("speed-code payload must be 3 bytes with a code index 0..7")
    return (data[0] << 8) | data[1], data[2]

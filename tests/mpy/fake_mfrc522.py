"""A register-level fake MFRC522 that also plays its SPI bus (CPython and MicroPython unix port): hand it to the
driver as the `spi` (write, write_readinto; transfer(tx) -> rx is one transaction).

It speaks the chip's SPI protocol: the first byte of a transaction is the address (reg << 1) & 0x7E, with 0x80 set
for a read; in a read the chip answers byte k with the register named by byte k-1. It ignores the bus while chip
select is high, keeps a FIFO, and runs Transceive when StartSend is set, as an ISO 14443A card in the field answers
while the antenna is on: REQA (7-bit 0x26) gets the ATQA 0x0004; anticollision (0x93 / 0x95 / 0x97, 0x20) gets the
UID part of that cascade level + BCC (a 7-byte `uid`: 0x88 and its first three bytes at level 1, the other four at
level 2; a 10-byte one: 0x88 and three bytes at levels 1 and 2, the last four at level 3);
SELECT (level, 0x70, part, CRC_A) gets the SAK + CRC_A (0x04 at level 1 of a 7-byte UID, else `sak`); a Type 2 READ
(0x30, page, CRC_A) gets 16 bytes of `memory` from that page + CRC_A (`corrupt_read` flips a bit in it). Anything
else, or a frame with a wrong CRC_A, times out (TimerIRq). `absent_value` set to 0x00 or 0xFF makes it an unplugged
reader: every read returns that byte.
"""

from drivers.mfrc522 import crc_a

_COMMAND = 0x01
_COM_IRQ = 0x04
_ERROR = 0x06
_FIFO_DATA = 0x09
_FIFO_LEVEL = 0x0A
_CONTROL = 0x0C
_BIT_FRAMING = 0x0D
_TX_CONTROL = 0x14
_VERSION = 0x37

_SOFT_RESET = 0x0F
_TRANSCEIVE = 0x0C
_REQA = 0x26
_ATQA = (0x04, 0x00)


class FakeMfrc522:
    def __init__(self, cs, version=0x92):
        self.cs = cs
        self.version = version
        self.absent_value = None
        self.uid = None                # 4, 7 or 10 bytes of the card in the field, or None
        self.sak = 0x00                # SAK of the card once its UID is complete: 0x00 Type 2 (NTAG), 0x08 Classic
        self.memory = bytearray(180)   # the card's pages (4 bytes each), for READ
        self.corrupt_bcc = False
        self.corrupt_read = False
        self.regs = bytearray(64)
        self.fifo = []
        self.resets = 0
        self.transceives = 0
        self.bad_addresses = 0

    def transfer(self, tx):
        if self.cs.value() != 0:
            return b"\xff" * len(tx)
        if tx[0] & 0x01:
            self.bad_addresses += 1
        reg = (tx[0] >> 1) & 0x3F
        rx = bytearray(len(tx))
        if tx[0] & 0x80:
            for k in range(1, len(tx)):
                rx[k] = self._read(reg)
                reg = (tx[k] >> 1) & 0x3F
        else:
            for k in range(1, len(tx)):
                self._write(reg, tx[k])
        return bytes(rx)

    def write_readinto(self, tx, rx):
        rx[:] = self.transfer(bytes(tx))

    def write(self, tx):
        self.transfer(bytes(tx))

    def _read(self, reg):
        if self.absent_value is not None:
            return self.absent_value
        if reg == _VERSION:
            return self.version
        if reg == _FIFO_DATA:
            return self.fifo.pop(0) if self.fifo else 0
        if reg == _FIFO_LEVEL:
            return len(self.fifo)
        return self.regs[reg]

    def _write(self, reg, value):
        if self.absent_value is not None:
            return
        if reg == _COMMAND:
            if value & 0x0F == _SOFT_RESET:
                self.regs = bytearray(64)
                self.fifo = []
                self.resets += 1
            else:
                self.regs[_COMMAND] = value & 0x0F
        elif reg == _FIFO_LEVEL:
            if value & 0x80:
                self.fifo = []
        elif reg == _FIFO_DATA:
            self.fifo.append(value)
        elif reg == _COM_IRQ:
            if value & 0x80:
                self.regs[_COM_IRQ] |= value & 0x7F
            else:
                self.regs[_COM_IRQ] &= 0xFF ^ (value & 0x7F)
        elif reg == _BIT_FRAMING:
            self.regs[_BIT_FRAMING] = value
            if value & 0x80 and self.regs[_COMMAND] == _TRANSCEIVE:
                self._transceive(value & 0x07)
        else:
            self.regs[reg] = value

    def _transceive(self, tx_last_bits):
        self.transceives += 1
        sent = self.fifo
        self.fifo = []
        self.regs[_ERROR] = 0
        self.regs[_CONTROL] = 0
        antenna = self.regs[_TX_CONTROL] & 0x03 == 0x03
        answer = None
        if antenna and self.uid is not None:
            if sent == [_REQA] and tx_last_bits == 7:
                answer = list(_ATQA)
            elif len(sent) == 2 and sent[0] in (0x93, 0x95, 0x97) and sent[1] == 0x20 and tx_last_bits == 0:
                u = self._part(sent[0])
                if u is not None:
                    bcc = u[0] ^ u[1] ^ u[2] ^ u[3]
                    if self.corrupt_bcc:
                        bcc ^= 0x01
                    answer = list(u) + [bcc]
            elif len(sent) >= 3 and tx_last_bits == 0 and crc_a(bytes(sent[:-2])) == sent[-2] | sent[-1] << 8:
                answer = self._framed(sent[:-2])
        if answer is None:
            self.regs[_COM_IRQ] |= 0x01         # TimerIRq: nobody answered
        else:
            self.fifo = answer
            self.regs[_COM_IRQ] |= 0x30         # RxIRq | IdleIRq

    def _part(self, level):
        """The 4 UID bytes a cascade level answers with, or None."""
        u = self.uid
        k = (level - 0x93) // 2                      # 0, 1, 2 for cascade levels 1-3
        parts = len(u) // 3                          # 1, 2, 3 levels for 4, 7, 10 bytes
        if k >= parts:
            return None
        if k == parts - 1:
            return u[3 * k:3 * k + 4]
        return bytes((0x88,)) + u[3 * k:3 * k + 3]

    def _framed(self, frame):
        """The answer (with CRC_A) to a CRC-framed command: SELECT or READ; None for anything else."""
        if len(frame) == 7 and frame[0] in (0x93, 0x95, 0x97) and frame[1] == 0x70:
            part = self._part(frame[0])
            if part is None or list(frame[2:6]) != list(part):
                return None
            body = [0x04 if part[0] == 0x88 and (frame[0] - 0x93) // 2 < len(self.uid) // 3 - 1 else self.sak]
        elif len(frame) == 2 and frame[0] == 0x30 and self.sak == 0x00:
            start = frame[1] * 4
            body = [self.memory[(start + k) % len(self.memory)] for k in range(16)]
            if self.corrupt_read:
                body[5] ^= 0x10
        else:
            return None
        crc = crc_a(bytes(body))
        if self.corrupt_read and frame[0] == 0x30:
            crc = crc_a(bytes(body[:5] + [body[5] ^ 0x10] + body[6:]))   # the CRC of what the card meant to send
        return body + [crc & 0xFF, crc >> 8]

"""A register-level fake MFRC522 that also plays its SPI bus (CPython and MicroPython unix port): hand it to the
driver as the `spi` (write, write_readinto; transfer(tx) -> rx is one transaction).

It speaks the chip's SPI protocol: the first byte of a transaction is the address (reg << 1) & 0x7E, with 0x80 set
for a read; in a read the chip answers byte k with the register named by byte k-1. It ignores the bus while chip
select is high, keeps a FIFO, and runs Transceive when StartSend is set: REQA (7-bit 0x26) gets the ATQA 0x0004 and
anticollision CL1 (0x93 0x20) gets UID + BCC while a card is in the field and the antenna is on; anything else times
out (TimerIRq). `absent_value` set to 0x00 or 0xFF makes it an unplugged reader: every read returns that byte.
"""

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
        self.uid = None                # 4 bytes of the card in the field, or None
        self.corrupt_bcc = False
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
            elif sent == [0x93, 0x20] and tx_last_bits == 0:
                u = self.uid
                bcc = u[0] ^ u[1] ^ u[2] ^ u[3]
                if self.corrupt_bcc:
                    bcc ^= 0x01
                answer = [u[0], u[1], u[2], u[3], bcc]
        if answer is None:
            self.regs[_COM_IRQ] |= 0x01         # TimerIRq: nobody answered
        else:
            self.fifo = answer
            self.regs[_COM_IRQ] |= 0x30         # RxIRq | IdleIRq

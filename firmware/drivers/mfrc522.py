"""NXP MFRC522 13.56 MHz reader on SPI: reads the UID of ISO 14443A tags laid between the rails, and a balise's data.

Mfrc522(spi, cs, rst) takes a ready `machine.SPI` (mode 0, up to 10 MHz, MSB first) and ready output pins for chip
select and reset (rst None: the chip's NRSTPD is tied high and its soft reset is the reset). Register access: one SPI
transaction per register, address byte (reg << 1) & 0x7E, with 0x80 set to read. A reader that does not answer
(version register not one of the known chips, or the bus raising OSError) leaves `present` False; then `poll` returns
None and nothing ever raises.

A read runs REQA, then anticollision and SELECT at cascade level 1 and, for a 7-byte UID (NTAG, Ultralight), level
2, and for a 10-byte one level 3; a uid is read whole or not at all. When the tag is a Type 2 tag (SAK 0x00:
NTAG213/215, Ultralight), it then READs pages 4-7: a balise's 16 data bytes, which hold its Hamming-coded telegram
(position and id, see firmware/telegram.py); they are kept as 32 hex
digits in `data` (None for other tags, such as MIFARE Classic, or when the answer's CRC is wrong). Frames after the
anticollision carry ISO 14443A's CRC_A, computed and checked here.
"""

try:
    from micropython import const
except ImportError:  # CPython
    def const(value):
        return value

try:
    from cbtc.firmware import wire  # the controller's package
except ImportError:
    import wire  # a board holds the firmware's modules at the top level

# registers
_COMMAND = const(0x01)        # CommandReg: starts and stops commands
_COM_IRQ = const(0x04)        # ComIrqReg: interrupt request bits
_ERROR = const(0x06)          # ErrorReg: error bits of the last command
_FIFO_DATA = const(0x09)      # FIFODataReg: input and output of the 64-byte FIFO
_FIFO_LEVEL = const(0x0A)     # FIFOLevelReg: bytes in the FIFO; bit 7 flushes
_CONTROL = const(0x0C)        # ControlReg: RxLastBits in bits 2..0
_BIT_FRAMING = const(0x0D)    # BitFramingReg: StartSend bit 7, TxLastBits in bits 2..0
_MODE = const(0x11)           # ModeReg: CRC preset
_TX_CONTROL = const(0x14)     # TxControlReg: antenna drivers TX1/TX2 in bits 1..0
_TX_ASK = const(0x15)         # TxASKReg: force 100 % ASK
_T_MODE = const(0x2A)         # TModeReg: timer auto start, prescaler high bits
_T_PRESCALER = const(0x2B)    # TPrescalerReg: prescaler low bits
_T_RELOAD_H = const(0x2C)     # TReloadReg high byte
_T_RELOAD_L = const(0x2D)     # TReloadReg low byte
_VERSION = const(0x37)        # VersionReg: chip type and version

# register bits and values
_CMD_IDLE = const(0x00)       # no action, cancels the current command
_CMD_TRANSCEIVE = const(0x0C)  # send the FIFO, then receive into it
_CMD_SOFT_RESET = const(0x0F)  # reset the chip
_POWER_DOWN = const(0x10)     # CommandReg bit: soft power-down (set while the reset runs)
_START_SEND = const(0x80)     # BitFramingReg: start transmission of Transceive
_FLUSH = const(0x80)          # FIFOLevelReg: flush the FIFO
_IRQ_ALL = const(0x7F)        # ComIrqReg: writing with bit 7 clear clears these bits
_IRQ_RX_IDLE = const(0x30)    # RxIRq | IdleIRq: the answer is in
_IRQ_TIMER = const(0x01)      # TimerIRq: no answer before the timer ran out
_ERR_FATAL = const(0x13)      # BufferOvfl | ParityErr | ProtocolErr
_ANTENNA_ON = const(0x03)     # TxControlReg: TX1 and TX2 on

# ISO 14443A
_REQA = const(0x26)           # request (7-bit short frame): idle cards answer with ATQA
_SEL_CL1 = const(0x93)        # select / anticollision, cascade level 1
_SEL_CL2 = const(0x95)        # select / anticollision, cascade level 2
_SEL_CL3 = const(0x97)        # select / anticollision, cascade level 3 (10-byte uids)
_NVB_ANTICOLL = const(0x20)   # number of valid bits: 2 bytes, ask for the whole UID
_NVB_SELECT = const(0x70)     # number of valid bits: 7 bytes, select this UID
_CASCADE_TAG = const(0x88)    # first UID byte at level 1 when the UID goes on at the next level
_SAK_MORE = const(0x04)       # SAK: the UID is not complete
_READ = const(0x30)           # Type 2 READ: 4 pages (16 bytes) from the page given
_BALISE_PAGE = const(4)       # first user page of NTAG/Ultralight: the balise telegram

_ABSENT_MS = const(300)       # a tag must be gone this long before it is reported again (ms)
_WAIT_LOOPS = const(400)      # register polls before a transceive is given up


def crc_a(data):
    """ISO 14443A CRC_A of `data`: preset 0x6363, sent low byte first (READ page 0, 30 00, carries 02 A8)."""
    crc = 0x6363
    for b in data:
        b ^= crc & 0xFF
        b = (b ^ (b << 4)) & 0xFF
        crc = (crc >> 8) ^ (b << 8) ^ (b << 3) ^ (b >> 4)
    return crc & 0xFFFF


class Mfrc522:
    # state every reader starts with (class attributes: an instance pays for one only once it changes it)
    version = 0               # VersionReg as read at start
    present = False           # a known chip answered and was set up
    data = None               # the last tag's pages 4-7 as 32 hex digits (a balise), or None
    _last_uid = None
    _last_seen_ms = 0

    def __init__(self, spi, cs, rst):
        self.spi = spi
        self.cs = cs
        self.rst = rst
        self._tx = bytearray(2)
        self._rx = bytearray(2)
        try:
            cs.value(1)
            if rst is not None:   # None: NRSTPD tied to 3.3 V, the soft reset below is the reset
                rst.value(1)
            self.version = self._read(_VERSION)
            if self.version not in (0x91, 0x92, 0x88, 0x12):   # MFRC522 v1.0, v2.0, FM17522 clone, another clone
                return
            self._write(_COMMAND, _CMD_SOFT_RESET)
            for _ in range(_WAIT_LOOPS):
                if not self._read(_COMMAND) & _POWER_DOWN:
                    break
            self._write(_T_MODE, 0x8D)        # timer starts after sending; prescaler 0xD3E: 2 kHz ticks
            self._write(_T_PRESCALER, 0x3E)
            self._write(_T_RELOAD_H, 0)
            self._write(_T_RELOAD_L, 2)       # 2 ticks: 1 ms answer timeout (the timer stops at an answer's 5th
            #                                   bit; a tag answers within 0.1 ms): a poll that finds no tag is short
            self._write(_TX_ASK, 0x40)
            self._write(_MODE, 0x3D)          # CRC preset 0x6363 (ISO 14443A)
            self._write(_TX_CONTROL, self._read(_TX_CONTROL) | _ANTENNA_ON)
            self.present = True
        except OSError:   # the bus failed: no reader
            self.present = False

    # --- registers ---------------------------------------------------------------------------------------

    def _write(self, reg, value):
        self._tx[0] = (reg << 1) & 0x7E
        self._tx[1] = value
        self.cs.value(0)
        try:
            self.spi.write(self._tx)
        finally:
            self.cs.value(1)

    def _read(self, reg):
        self._tx[0] = ((reg << 1) & 0x7E) | 0x80
        self._tx[1] = 0
        self.cs.value(0)
        try:
            self.spi.write_readinto(self._tx, self._rx)
        finally:
            self.cs.value(1)
        return self._rx[1]

    # --- tags ----------------------------------------------------------------------------------------------

    def _transceive(self, data, tx_last_bits):
        """Send `data` (bytes), last byte with `tx_last_bits` bits (0 = 8); the answer bytes or None."""
        self._write(_COMMAND, _CMD_IDLE)
        self._write(_COM_IRQ, _IRQ_ALL)
        self._write(_FIFO_LEVEL, _FLUSH)
        for byte in data:
            self._write(_FIFO_DATA, byte)
        self._write(_BIT_FRAMING, tx_last_bits)
        self._write(_COMMAND, _CMD_TRANSCEIVE)
        self._write(_BIT_FRAMING, tx_last_bits | _START_SEND)
        irq = 0
        for _ in range(_WAIT_LOOPS):
            irq = self._read(_COM_IRQ)
            if irq & (_IRQ_RX_IDLE | _IRQ_TIMER):
                break
        self._write(_BIT_FRAMING, tx_last_bits)
        if not irq & _IRQ_RX_IDLE or irq & _IRQ_TIMER:
            return None
        if self._read(_ERROR) & _ERR_FATAL:
            return None
        count = self._read(_FIFO_LEVEL)
        if count > 18:
            return None
        data = bytearray(count)
        for i in range(count):
            data[i] = self._read(_FIFO_DATA)
        return bytes(data)

    def _call(self, data):
        """Send `data` with its CRC_A; the answer without its CRC, or None (no answer, or a wrong CRC)."""
        crc = crc_a(data)
        answer = self._transceive(data + bytes((crc & 0xFF, crc >> 8)), 0)
        if answer is None or len(answer) < 3:
            return None
        crc = crc_a(answer[:-2])
        if answer[-2] != crc & 0xFF or answer[-1] != crc >> 8:
            return None
        return answer[:-2]

    def read_uid(self):
        """Upper-case hex UID (8, 14 or 20 characters: 4, 7 or 10 bytes) of a tag in the field, or None (no tag, a
        garbled answer, no reader); `data` then holds a Type 2 tag's pages 4-7 (see the module's description)."""
        self.data = None
        if not self.present:
            return None
        atqa = self._transceive(bytes((_REQA,)), 7)
        if atqa is None or len(atqa) != 2:
            return None
        uid = ""
        more = True
        for level in (_SEL_CL1, _SEL_CL2, _SEL_CL3):
            part = self._transceive(bytes((level, _NVB_ANTICOLL)), 0)
            if part is None or len(part) != 5 or part[0] ^ part[1] ^ part[2] ^ part[3] != part[4]:
                return None
            sak = self._call(bytes((level, _NVB_SELECT)) + part)
            if sak is None or len(sak) != 1:
                return None
            more = sak[0] & _SAK_MORE
            if more and part[0] != _CASCADE_TAG:   # more to come, but no cascade tag: a garbled answer
                return None
            for byte in part[1:4] if more else part[:4]:
                uid += "%02X" % byte
            if not more:
                break
        if more:   # still incomplete after three levels: no card has such a uid
            return None
        if sak[0] == 0:   # Type 2: read the balise's pages
            pages = self._call(bytes((_READ, _BALISE_PAGE)))
            if pages is not None and len(pages) == 16:
                self.data = "".join("%02x" % byte for byte in pages)
        return uid

    def poll(self, now_ms):
        """A read at board time `now_ms` (monotonic ms): a tag's UID once per passage, else None. Every call reads
        (the board's loop sets the pace, and reports how long it was between two reads); the same UID is reported
        again only after it has been absent for 300 ms.
        """
        if not self.present:
            return None
        uid = self.read_uid()
        if uid is None:
            return None
        fresh = uid != self._last_uid or wire.wrap_diff(now_ms, self._last_seen_ms) >= _ABSENT_MS
        self._last_uid = uid
        self._last_seen_ms = now_ms
        return uid if fresh else None

"""The track circuit's speed-code channel: the BART radio ATC's fixed-block speed codes sent as
Hill's Hamming-coded telegrams.

The wayside encodes each code as a Hamming-coded telegram (firmware/telegram.py: sync, SECDED nibbles, CRC-8,
final parity) naming the block it is for; the rails flip each bit independently with probability `ber`; the train
decodes. A telegram the decoder rejects, or one for another block, gives the most restrictive code (0: stop at the
end of this block), so a corrupted code can only make a train more cautious. Counters say what the channel did.
Pure apart from its own seeded random source.
"""

import random

from cbtc.errors import ConfigError
from cbtc.protocol import telegram


class SpeedCodeChannel:
    def __init__(self, ber: float = 0.0, seed: int = 0):
        if not 0.0 <= ber < 0.5:
            raise ConfigError(f"speed-code channel: the bit-error rate (--code-ber) is a probability in [0, 0.5), "
                              f"got {ber}")
        self.ber = ber
        self._rng = random.Random(seed)
        self.counts = {"sent": 0, "ok": 0, "corrected": 0, "detected": 0, "undetected": 0}

    def transmit(self, block_index: int, code_index: int) -> int:
        """The code index the train decodes for `code_index` sent in block `block_index` (0 if rejected)."""
        frame = telegram.encode(telegram.speed_code_payload(block_index, code_index))
        if self.ber > 0.0:
            rng = self._rng
            for i in range(len(frame)):
                if rng.random() < self.ber:
                    frame[i] ^= 1
        data, status = telegram.decode(frame)
        self.counts["sent"] += 1
        if status == telegram.DETECTED:
            self.counts["detected"] += 1
            return 0
        block, received = telegram.parse_speed_code_payload(data)
        if block != block_index:
            self.counts["detected"] += 1
            return 0
        if received != code_index:
            self.counts["undetected"] += 1
        else:
            self.counts[status] += 1
        return received

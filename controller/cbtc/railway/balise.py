"""Balises that carry their own position: an RFID tag whose data holds a Hamming-coded telegram
(Hill's track-circuit telegram coding).

The telegram (firmware/telegram.py, balise profile: tag id, position along the track in mm, flags) is written once
into the tag's 16 data bytes (NTAG/Ultralight pages 4-7, `cbtc balise image` prints them); the board reads them with
the tag's UID and reports them as 32 hex digits. The controller decodes them here: a clean or corrected telegram
gives the tag's position without any survey table; a rejected one (two or more bit errors) leaves the UID's entry in
the layout, if there is one. A telegram that disagrees with the layout by more than `MISMATCH_M` means the tag was
moved or the layout is out of date: the read is not used and the mismatch is counted, so nobody trusts either.
"""

from cbtc.protocol import telegram

IMAGE_BYTES = 16
FRAME_BITS = telegram.frame_bits(6)      # 126: the balise telegram
MISMATCH_M = 0.005


def image(tag_id: int, s_m: float, flags: int = 0) -> bytes:
    """The 16 data bytes to write into a balise tag for tag `tag_id` at `s_m` metres along the track."""
    frame = telegram.encode(telegram.balise_payload(tag_id, int(round(s_m * 1000.0)), flags))
    return telegram.pack(frame).ljust(IMAGE_BYTES, b"\x00")


def read(data_hex: str):
    """(tag_id, s_m, status) of a balise's data as the board reported it (32 hex digits); status is "ok",
    "corrected" or "detected" (then tag_id and s_m are None). ValueError if it is not 16 bytes of hex."""
    try:
        data = bytes.fromhex(data_hex)
    except (TypeError, ValueError):
        raise ValueError(f"balise data {data_hex!r} is not hex") from None
    if len(data) != IMAGE_BYTES:
        raise ValueError(f"balise data is {len(data)} bytes; a balise holds {IMAGE_BYTES}")
    payload, status = telegram.decode(telegram.unpack(data, FRAME_BITS))
    if payload is None:
        return None, None, status
    tag_id, s_mm, _flags = telegram.parse_balise_payload(payload)
    return tag_id, s_mm / 1000.0, status


class BaliseReader:
    """Where a tag read puts the train: from the tag's telegram when it carries one, else from the layout's UID
    table; with counters of what happened (for the estimators' `counters()` and the supervision)."""

    def __init__(self, layout):
        self.layout = layout
        self.counts = {"telegram_ok": 0, "telegram_corrected": 0, "telegram_rejected": 0, "mismatch": 0,
                       "unknown": 0}

    def position_m(self, uid: str, data_hex=None):
        """The tag's position along the track (m), or None when the read cannot be used."""
        listed = self.layout.tag_by_uid(uid)
        if data_hex:
            try:
                _tag_id, s_m, status = read(data_hex)
            except ValueError:
                s_m, status = None, telegram.DETECTED
            if s_m is not None:
                self.counts["telegram_" + status] += 1
                if listed is not None and min(abs(self.layout.ahead_m(listed.s_m, s_m)),
                                              abs(self.layout.ahead_m(s_m, listed.s_m))) > MISMATCH_M:
                    self.counts["mismatch"] += 1
                    return None
                return self.layout.wrap(s_m)
            self.counts["telegram_rejected"] += 1
        if listed is None:
            self.counts["unknown"] += 1
            return None
        return listed.s_m

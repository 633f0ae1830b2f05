"""The zone controller's half of the wire protocol (wire.py): report decoding and validation, command encoding, zone
topics, the mode and fault names.

Part of the one protocol definition, in a module of its own because a board never needs it: wire.py reaches these
names on first use (`wire.decode_report`, `wire.MODES`), so a board never loads this module into its small heap.
"""


try:
    from . import wire  # the controller imports the firmware as the package cbtc.firmware
except ImportError:
    import wire  # top level, as under the MicroPython unix port

BOOT_MAX, INT31, MAX_TAGS, VERSION, WireError = wire.BOOT_MAX, wire.INT31, wire.MAX_TAGS, wire.VERSION, wire.WireError
WRAP_MASK = wire.WRAP_MASK
check_fields, check_ints, decode_sealed = wire.check_fields, wire.check_ints, wire.decode_sealed
dumps_compact, seal, topic_command = wire.dumps_compact, wire.seal, wire.topic_command

try:
    from micropython import const
except ImportError:  # CPython
    def const(value):
        return value

_POS_MM = const(1000000)   # IPS coordinates stay within +-1 km (mm)

MODES = ("idle", "run", "stop", "trip")
FAULTS = ("ips_silent", "ips_crc", "rfid_absent", "enc_stall", "enc_fail", "cmd_timeout", "cmd_reject",
          "broker_lost", "guard", "roll", "undriven", "hold", "reverse", "split")
REPORT_FILTER = "cbtc/train/+/report"


def topic_zone_status(zone_id):
    return "cbtc/zc/" + zone_id + "/status"


# --- reports ---------------------------------------------------------------------------------------------------

# a report's integer fields, all required: (name, lowest, highest) flat; then its other fields (`rng` optional)
REPORT_INTS = ("boot", 1, BOOT_MAX, "seq", 0, WRAP_MASK, "t_ms", 0, WRAP_MASK, "odo_mm", -INT31, INT31,
               "v_mmps", -20000, 20000, "duty", -100, 100,
               "cseq", -1, WRAP_MASK, "csid", -1, INT31)
REPORT_OTHER = ("mode", "ips", "tags", "rng", "flt")
SPAN_MAX_MS = 65535   # a tag read's span: the time since the reader's previous poll that answered (ms)
TAG_INTS = ("odo_mm", -INT31, INT31, "t_ms", 0, WRAP_MASK, "span_ms", 0, SPAN_MAX_MS)
UID_HEX_LENGTHS = (8, 14, 20)   # MFRC522 uids of 4, 7 and 10 bytes
_HEX = "0123456789abcdefABCDEF"


def decode_report(key, topic, payload):
    """The report dict of a sealed payload, validated; WireError with the reason otherwise."""
    return check_report(decode_sealed(key, topic, payload, "rep", REPORT_INTS), topic)


def _null_or_ints(msg, field, specs, topic, required):
    """Check msg[field]: null (or absent unless `required`), or a list of integers following `specs` (see
    wire.check_ints)."""
    if required and field not in msg:
        raise WireError("field %r on %s is missing (null when there is nothing to report)" % (field, topic))
    value = msg.get(field)
    if value is not None:
        if not isinstance(value, list) or len(value) != len(specs) // 3:
            names = ""
            for i in range(0, len(specs), 3):
                names += ", " + specs[i]
            raise WireError("field %r on %s must be null or [%s]" % (field, topic, names[2:]))
        check_ints(value, specs, topic, field)
    msg[field] = value


def _is_hex(text, lengths):
    if not isinstance(text, str) or len(text) not in lengths:
        return False
    for ch in text:
        if ch not in _HEX:
            return False
    return True


def check_report(msg, topic):
    """`msg` (a report whose header and integer fields wire has checked) if its mode, ips, tags, rng and flt are
    valid and it has no other field; WireError with the reason otherwise."""
    check_fields(msg, REPORT_INTS, topic, REPORT_OTHER)
    if msg.get("mode") not in MODES:
        raise WireError("field 'mode' on %s is %r, not one of %s" % (topic, msg.get("mode"), ", ".join(MODES)))
    _null_or_ints(msg, "ips", ("t_ms", 0, WRAP_MASK, "x_mm", -_POS_MM, _POS_MM, "y_mm", -_POS_MM, _POS_MM), topic, True)
    tags = msg.get("tags")
    if not isinstance(tags, list) or len(tags) > MAX_TAGS:
        raise WireError("field 'tags' on %s must be a list of at most %d [uid, odo_mm, t_ms, span_ms(, data)]"
                        % (topic, MAX_TAGS))
    for tag in tags:
        if (not isinstance(tag, list) or not 4 <= len(tag) <= 5 or not _is_hex(tag[0], UID_HEX_LENGTHS)
                or (len(tag) == 5 and not _is_hex(tag[4], (32,)))):
            raise WireError("entry %r of 'tags' on %s must be [uid: 8, 14 or 20 hex digits, odo_mm, t_ms, span_ms] or "
                            "[uid, odo_mm, t_ms, span_ms, data: 32 hex digits of the balise telegram]" % (tag, topic))
        check_ints(tag[1:4], TAG_INTS, topic, "tags")
    _null_or_ints(msg, "rng", ("t_ms", 0, WRAP_MASK, "gap_mm", -100000, _POS_MM), topic, False)
    faults = msg.get("flt")
    bad = not isinstance(faults, list)
    for name in [] if bad else faults:
        bad = bad or name not in FAULTS
    if bad:
        raise WireError("field 'flt' on %s must list fault names from %s" % (topic, ", ".join(FAULTS)))
    return msg


# --- commands --------------------------------------------------------------------------------------------------

def encode_command(key, train_id, boot, seq, sid, rseq, v_mmps, eoa_mm, ttl_ms, acc_mmps2, dec_mmps2, stop_mm=None,
                   rpt_ms=0, odo_mm_per_m=1000):
    """Sealed command payload.

    boot: the boot id of the train's report rseq (the board refuses a command of another boot); sid: the
    controller's session id (a new random int each start); seq: increasing within a session;
    rseq: the report this command is based on; v_mmps: speed ceiling (mm/s, >= 0); eoa_mm: end of authority as a
    value of the train's own odometer (mm) that its head must not pass (supervised by the trip curve); ttl_ms:
    validity, counted on the board's clock from the time of report rseq; acc_mmps2 / dec_mmps2: acceleration and
    service deceleration to use (mm/s^2); stop_mm: a service stop target (odometer mm: a station), braked to at the
    service rate and held, not supervised by the trip curve (None: no stop short of eoa_mm); rpt_ms: the report
    period the controller asks for while this command is valid (ms; 0: the board's own); odo_mm_per_m: a low
    bound of the board's odometer millimetres per true metre (its encoder's scale, 1000: it reads true), which the
    board's braking curves scale its decelerations by, so they hold in true metres.
    """
    if stop_mm is None:
        stop_mm = eoa_mm
    ints = (boot, seq, sid, rseq, v_mmps, eoa_mm, ttl_ms, acc_mmps2, dec_mmps2, stop_mm, rpt_ms, odo_mm_per_m)
    body = _plain_command_body(train_id, ints)
    if body is None:   # whatever a caller passes (a test's bool, float or odd id) is written as JSON writes it
        msg = {"v": VERSION, "k": "cmd", "id": train_id}
        for i in range(len(ints)):
            msg[_COMMAND_KEYS[i]] = ints[i]
        body = dumps_compact(msg)
    return seal(key, topic_command(train_id), body.encode())


def _plain_command_body(train_id, ints):
    """A command's JSON text for `ints` (encode_command's fields from boot on, in order) when every one is an int and
    the id plain: the bytes json.dumps writes for them (an int's repr; an id of letters, digits, '_' and '-'), made
    at a fifth of its cost, as a zone sends a command for most reports. None otherwise."""
    if _plain_id(train_id) and set(map(type, ints)) == _INT_ONLY:
        return _COMMAND_JSON % ((VERSION, train_id) + ints)
    return None


_COMMAND_KEYS = ("boot", "seq", "sid", "rseq", "v_mmps", "eoa_mm", "ttl_ms", "acc", "dec", "stop_mm", "rpt_ms",
                 "odo_mm_per_m")
_COMMAND_JSON = '{"v":%d,"k":"cmd","id":"%s",' + ",".join('"%s":%%d' % name for name in _COMMAND_KEYS) + "}"


_INT_ONLY = {int}   # the types of a command's fields when every one is an int (a bool is not)
_PLAIN_IDS = set()  # ids found plain already: a zone commands the same few trains at every report


def _plain_id(train_id):
    """True for an id check_train_id allows (letters, digits, '_' and '-'): JSON writes it unescaped."""
    if type(train_id) is str and train_id in _PLAIN_IDS:
        return True
    try:
        wire.check_train_id(train_id)
    except WireError:
        return False
    if len(_PLAIN_IDS) >= 1024:
        _PLAIN_IDS.clear()
    _PLAIN_IDS.add(train_id)
    return True

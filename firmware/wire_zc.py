"""The zone controller's half of the wire protocol (wire.py): report decoding and validation, command encoding, zone
topics, the mode and fault names.

Part of the one protocol definition, in a module of its own because a board never needs it; its checks and its
encoder are made from the message table (messages.py).
"""


try:
    from . import messages, wire  # the controller imports the firmware as the package cbtc.firmware
except ImportError:
    import messages  # top level, as under the MicroPython unix port
    import wire

MAX_TAGS, VERSION, WireError = wire.MAX_TAGS, wire.VERSION, wire.WireError
check_fields, check_ints, decode_sealed = wire.check_fields, wire.check_ints, wire.decode_sealed
dumps_compact, topic_command = wire.dumps_compact, wire.topic_command

MODES, FAULTS, SPAN_MAX_MS, UID_HEX_LENGTHS = messages.MODES, messages.FAULTS, messages.SPAN_MAX_MS, \
    messages.UID_HEX_LENGTHS
REPORT_FILTER = "cbtc/train/+/report"


def topic_zone_status(zone_id):
    return "cbtc/zc/" + zone_id + "/status"


def topic_zone_info(zone_id):
    return "cbtc/zc/" + zone_id + "/info"


# --- reports ---------------------------------------------------------------------------------------------------

REPORT_INTS = messages.int_specs(messages.REPORT)   # a report's integer fields, all required: (name, lo, hi) flat
REPORT_OTHER = tuple(f[0] for f in messages.REPORT[1] if f[1] != "int")   # its other fields (`rng` optional)
TAG_INTS, IPS_INTS, RNG_INTS = messages.TAG, messages.IPS, messages.RANGING
_HEX = "0123456789abcdefABCDEF"


def decode_report(key, topic, payload, mac=wire.mac_hex, loads=wire.json.loads):
    """The report dict of a sealed payload, validated (`mac` and `loads` as for wire.decode_sealed); WireError
    with the reason otherwise."""
    return check_report(decode_sealed(key, topic, payload, "rep", REPORT_INTS, mac, loads), topic)


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
    """`msg` (a report whose header and integer fields wire has checked) if its mode, ips, tags, rng, dir and flt are
    valid and it has no other field; WireError with the reason otherwise."""
    check_fields(msg, REPORT_INTS, topic, REPORT_OTHER)
    if msg.get("mode") not in MODES:
        raise WireError("field 'mode' on %s is %r, not one of %s" % (topic, msg.get("mode"), ", ".join(MODES)))
    _null_or_ints(msg, "ips", IPS_INTS, topic, True)
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
    _null_or_ints(msg, "rng", RNG_INTS, topic, False)
    back = msg.get("dir", 0)   # absent: forward
    if type(back) is not int or back not in (0, 1):
        raise WireError("field 'dir' on %s must be 0 or 1 (or absent), got %r" % (topic, back))
    faults = msg.get("flt")
    bad = not isinstance(faults, list)
    for name in [] if bad else faults:
        bad = bad or name not in FAULTS
    if bad:
        raise WireError("field 'flt' on %s must list fault names from %s" % (topic, ", ".join(FAULTS)))
    return msg


# --- commands --------------------------------------------------------------------------------------------------

def command_encoder(message=messages.COMMAND, defaults=messages.COMMAND_DEFAULTS, sealer=wire.seal):
    """(encode_command, plain_body) for a command table (messages.COMMAND; a test passes a copy with a field added):
    the encoder of a sealed payload from its fields (sealed by `sealer`), and the JSON text of a body of plain
    fields (or None)."""
    keys = messages.names(message)
    template = '{"v":%d,"k":"cmd","id":"%s",' + ",".join('"%s":%%d' % name for name in keys) + "}"

    def encode_command(key, train_id, *values, **named):
        """Sealed command payload of the fields of the command table, in its order or by name (the table says each
        field's meaning, bounds and unit); those of `defaults` may be left out (stop_mm, rpt_ms, odo_mm_per_m)."""
        ints = fields_of(keys, defaults, values, named)
        body = plain_body(train_id, ints)
        if body is None:   # whatever a caller passes (a test's bool, float or odd id) is written as JSON writes it
            msg = {"v": VERSION, "k": "cmd", "id": train_id}
            for i in range(len(ints)):
                msg[keys[i]] = ints[i]
            body = dumps_compact(msg)
        return sealer(key, topic_command(train_id), body.encode())

    def plain_body(train_id, ints):
        """A command's JSON text for `ints` (its fields in the table's order) when every one is an int and the id
        plain: the bytes json.dumps writes for them (an int's repr; an id of letters, digits, '_' and '-'), made for
        less than json.dumps costs, as a zone sends a command for most reports. None otherwise."""
        if _plain_id(train_id) and set(map(type, ints)) == _INT_ONLY:
            return template % ((VERSION, train_id) + ints)
        return None

    return encode_command, plain_body


def fields_of(keys, defaults, values, named):
    """The tuple of a message's fields in the order of `keys`: `values` by position, then `named` by name, then
    `defaults` (a string there names the field whose value it takes; None given is as if left out); WireError naming
    a field missing or unknown. Every field given in order, none None: `values` itself, as the zone gives them."""
    if len(values) == len(keys) and not named and None not in values:
        return values
    if len(values) > len(keys):
        raise WireError("%d fields given; the message has %d: %s" % (len(values), len(keys), ", ".join(keys)))
    given = dict(zip(keys, values))
    for name in named:
        if name not in keys or name in given:
            raise WireError("field %r is %s" % (name, "given twice" if name in given else "not in the message"))
        given[name] = named[name]
    out = []
    for name in keys:
        if name in given and not (given[name] is None and name in defaults):   # None: as if left out
            out.append(given[name])
        elif name in defaults:
            default = defaults[name]
            out.append(given[default] if isinstance(default, str) else default)
        else:
            raise WireError("field %r is missing (the message has %s)" % (name, ", ".join(keys)))
    return tuple(out)


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


encode_command, plain_command_body = command_encoder()

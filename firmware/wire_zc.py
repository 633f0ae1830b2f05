"""Validation of a report's body fields beyond its header and integers (see wire.decode_report).

Part of the wire protocol (wire.py), in a module of its own because only the zone controller decodes reports:
wire.decode_report imports it on first use, so a board never loads it into its small heap.
"""

from wire import FAULTS, INT31, MAX_TAGS, MODES, WireError, check_ints

try:
    from micropython import const
except ImportError:  # CPython
    def const(value):
        return value

_POS_MM = const(1000000)   # IPS coordinates stay within +-1 km (mm)


def _null_or_ints(msg, field, specs, topic):
    """Check msg[field]: null (or absent), or a list of integers following `specs` (see wire.check_ints)."""
    value = msg.get(field)
    if value is not None:
        if not isinstance(value, list) or len(value) != len(specs) // 3:
            names = ""
            for i in range(0, len(specs), 3):
                names += ", " + specs[i]
            raise WireError("field %r on %s must be null or [%s]" % (field, topic, names[2:]))
        check_ints(value, specs, topic, field)
    msg[field] = value


def check_report(msg, topic):
    """`msg` (a report whose header and integer fields wire has checked) if its mode, ips, tags, rng and flt are
    valid; WireError with the reason otherwise."""
    if msg.get("mode") not in MODES:
        raise WireError("field 'mode' on %s is %r, not one of %s" % (topic, msg.get("mode"), ", ".join(MODES)))
    _null_or_ints(msg, "ips", ("t_ms", 0, INT31, "x_mm", -_POS_MM, _POS_MM, "y_mm", -_POS_MM, _POS_MM), topic)
    tags = msg.get("tags")
    if not isinstance(tags, list) or len(tags) > MAX_TAGS:
        raise WireError("field 'tags' on %s must be a list of at most %d [uid, odo_mm, t_ms]" % (topic, MAX_TAGS))
    for tag in tags:
        if (not isinstance(tag, list) or len(tag) != 3 or not isinstance(tag[0], str)
                or not isinstance(tag[1], int) or not isinstance(tag[2], int)):
            raise WireError("entry %r of 'tags' on %s must be [uid_hex, odo_mm, t_ms]" % (tag, topic))
    _null_or_ints(msg, "rng", ("t_ms", 0, INT31, "gap_mm", -100000, _POS_MM), topic)
    faults = msg.get("flt")
    bad = not isinstance(faults, list)
    for name in [] if bad else faults:
        bad = bad or name not in FAULTS
    if bad:
        raise WireError("field 'flt' on %s must list fault names from %s" % (topic, ", ".join(FAULTS)))
    return msg

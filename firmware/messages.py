"""The message table: every message on the wire declared once, field by field: name, kind, bounds, unit, meaning.

The zone's encoders and decoders (wire_zc.py), the controller's fast path (cbtc/protocol/fast_wire.py) and
docs/protocol.md's tables are made from it; the board's own copy of the command's bounds (wire.COMMAND_INTS, kept
literal there because this module's text would cost a board's heap) is held equal to it by tests/test_messages.py.
MicroPython-compatible; it goes onto no train board.

A field is (name, kind, bounds, unit, meaning); the kinds:
  "const"  the header: bounds is the one value it may have (the kind and id are set per message)
  "id"     a train id, 1-16 characters of A-Z a-z 0-9 _ - (wire.check_train_id)
  "int"    bounds (lo, hi), inclusive; a bool or a float is not an integer; "int?" may be absent (read as lo)
  "choice" a string, one of bounds
  "names"  a list of strings, each one of bounds
  "list"   null or a list of integers, bounds a flat (name, lo, hi) spec (wire.check_ints); "list?" may be absent
  "tags"   a list of at most wire.MAX_TAGS tag reads, bounds the flat spec of their integers (wire_zc.check_report)
  "text"   a string of 1 to bounds characters
  "hex"    a string of exactly bounds lower-case hex digits
  "checks" an object {train id: a string of bounds lower-case hex digits}
A message is (kind, fields): kind is the `k` its header names. TOPICS says which topic carries which.
"""

try:
    from . import wire  # the controller imports the firmware as the package cbtc.firmware
except ImportError:
    import wire  # top level, as under the MicroPython unix port

BOOT_MAX, INT31, WRAP_MASK = wire.BOOT_MAX, wire.INT31, wire.WRAP_MASK
_POS_MM = 1000000   # IPS coordinates stay within +-1 km (mm)

MODES = ("idle", "run", "stop", "trip")
FAULTS = ("ips_silent", "ips_crc", "rfid_absent", "enc_stall", "enc_fail", "cmd_timeout", "cmd_reject",
          "broker_lost", "guard", "roll", "undriven", "hold", "reverse", "split")
STATUS = ("online", "offline")   # the retained payloads of a status topic (the board's and the zone's last will)
SPAN_MAX_MS = 65535   # a tag read's span: the time since the reader's previous poll that answered (ms)
UID_HEX_LENGTHS = (8, 14, 20)   # MFRC522 uids of 4, 7 and 10 bytes

IPS = ("t_ms", 0, WRAP_MASK, "x_mm", -_POS_MM, _POS_MM, "y_mm", -_POS_MM, _POS_MM)
TAG = ("odo_mm", -INT31, INT31, "t_ms", 0, WRAP_MASK, "span_ms", 0, SPAN_MAX_MS)   # a tag read after its uid
RANGING = ("t_ms", 0, WRAP_MASK, "gap_mm", -100000, _POS_MM)

HEADER = (
    ("v", "const", wire.VERSION, "", "protocol version"),
    ("k", "const", None, "", "kind"),
    ("id", "id", None, "", "train id, or the zone's in a zone's message (must equal the topic's)"),
)

REPORT = ("rep", (
    ("boot", "int", (1, BOOT_MAX), "",
     "boot id: drawn at random each time the board starts, the same in every report of that boot"),
    ("seq", "int", (0, WRAP_MASK), "", "report sequence number, +1 per report from boot, modulo 2^30"),
    ("t_ms", "int", (0, WRAP_MASK), "ms", "board uptime when sampled, modulo 2^30"),
    ("odo_mm", "int", (-INT31, INT31), "mm", "encoder odometer"),
    ("v_mmps", "int", (-20000, 20000), "mm/s",
     "encoder speed: the counts between two encoder edges at least `speed_window_ms` (20 ms) apart over the time "
     "between them"),
    ("duty", "int", (-100, 100), "%",
     "motor duty: the mean (floored) over the loop's passes since the previous report"),
    ("mode", "choice", MODES, "",
     "`idle` (no authority yet), `run`, `stop` (command expired: braking), `trip` (emergency brake)"),
    ("cseq", "int", (-1, WRAP_MASK), "", "seq of the last accepted command, -1 if none"),
    ("csid", "int", (-1, INT31), "",
     "session id (`sid`) of that command, -1 if none: the echo that shows the controller this report was made "
     "after its command arrived"),
    ("ips", "list", IPS, "ms, mm",
     "newest IPS fix since the last report, in the IPS frame, stamped with board time at receipt; required (null "
     "when there is none)"),
    ("tags", "tags", TAG, "mm, ms",
     "RFID tags read since the last report, with the odometer at the read, the time since the reader's previous "
     "poll that answered (the reader entered the tag's field within it: the controller takes the read's lateness "
     "from it and its own speed estimate, whatever the board's poll rate; time, not counts, because counts of a "
     "spinning wheel or a burst are not travel) and the balise telegram when the tag holds one"),
    ("flt", "names", FAULTS, "", "faults"),
    ("rng", "list?", RANGING, "ms, mm",
     "newest gap to the train ahead measured by train-to-train ranging (docs/source_systems.md); optional: boards "
     "without ranging leave it out"),
    ("dir", "int?", (0, 1), "",
     "1 while the board drives backwards (the `dir` it took last), absent forward: which way a train faces"),
))

COMMAND = ("cmd", (
    ("boot", "int", (1, BOOT_MAX), "",
     "the boot id of report `rseq`: the board takes only commands of its current boot"),
    ("seq", "int", (0, WRAP_MASK), "",
     "command sequence number, increasing (modulo 2^30) within a controller session"),
    ("sid", "int", (0, INT31), "", "controller session id, random at each controller start"),
    ("rseq", "int", (0, WRAP_MASK), "", "the report this command is based on"),
    ("v_mmps", "int", (0, 5000), "mm/s", "speed ceiling"),
    ("eoa_mm", "int", (-INT31, INT31), "mm",
     "end of authority, as a value of the train's own odometer: the head must not pass it (safety: the trip curve "
     "supervises it)"),
    ("ttl_ms", "int", (1, 10000), "ms", "validity, counted on the board's clock from the time of report `rseq`"),
    ("acc", "int", (1, 10000), "mm/s^2", "acceleration for reaching `v_mmps`"),
    ("dec", "int", (1, 10000), "mm/s^2",
     "deceleration for reaching `v_mmps`; the braking curve to `eoa_mm` always uses the train's own service "
     "deceleration"),
    ("stop_mm", "int", (-INT31, INT31), "mm",
     "service stop target, same frame: a station stop, braked to at the service rate and held; not supervised by "
     "the trip curve; `eoa_mm` when there is none"),
    ("rpt_ms", "int", (0, 10000), "ms",
     "the report period the controller asks for while this command is valid; 0: the board's own `report_ms`"),
    ("odo_mm_per_m", "int", (500, 2000), "mm/m",
     "a low bound of the train's encoder scale, odometer mm per true metre (1000: it reads true), floored: the "
     "board's curves scale their decelerations by it, and its speed loop the command's speed and rates"),
    ("dir", "int", (0, 1), "",
     "direction of travel: 0 the train's own forward (the motor's positive drive), 1 backwards. A board takes a "
     "change only standing (braked, its odometer still for 0.5 s), keeps nothing of the old direction's authority and "
     "counts its odometer on, up in the new direction: `eoa_mm` and `stop_mm` lie ahead in the new direction"),
))

ZONE_INFO = ("info", (
    ("sid", "int", (0, INT31), "", "the controller's session id (`sid` of its commands)"),
    ("layout", "text", 64, "", "the name of the layout the zone runs"),
    ("digest", "hex", 16, "",
     "the layout's digest: the first 16 hex digits of SHA-256 over its geometry, stations, tags, blocks and IPS "
     "frame (`Layout.digest`), the same for the same track whatever the file is called"),
    ("checks", "checks", 16, "",
     "a key check per train the zone governs: the first 16 hex digits of HMAC-SHA256(the train's key, "
     "`cbtc key check`), which shows a holder of the key that it is the zone's and reveals nothing of it"),
))

# every message type by its topic: (topic, direction, QoS, retained, what it carries: a message of this table, or
# the status payloads). Switch and hand-over messages join here, each with its own topic and table
TOPICS = (
    ("cbtc/train/<id>/report", "board -> controller", 0, False, REPORT),
    ("cbtc/train/<id>/cmd", "controller -> board", 0, False, COMMAND),
    ("cbtc/train/<id>/status", "board", 1, True, STATUS),
    ("cbtc/zc/<zone>/status", "controller", 1, True, STATUS),
    ("cbtc/zc/<zone>/info", "controller", 1, True, ZONE_INFO),
)

# what a command's field is when its encoder is not given it (a string: the value of the field it names); a field
# added to COMMAND needs an entry here only if a caller may leave it out
COMMAND_DEFAULTS = {"stop_mm": "eoa_mm", "rpt_ms": 0, "odo_mm_per_m": 1000, "dir": 0}


def int_specs(message):
    """The flat (name, lo, hi) spec (wire.check_ints) of a message's integer fields, in the table's order."""
    specs = ()
    for field in message[1]:
        if field[1] == "int":
            specs += (field[0], field[2][0], field[2][1])
    return specs


def names(message):
    """The names of a message's fields after the header, in the table's order (the order a body is written in)."""
    return tuple(field[0] for field in message[1])


def field(message, name):
    """The table's entry for field `name` of `message`; KeyError if it has none."""
    for entry in message[1]:
        if entry[0] == name:
            return entry
    raise KeyError(name)

"""The wire protocol, one definition for boards and controller: the firmware's own modules, imported as a package.

`wire` encodes, validates and authenticates every message; `telegram` is the Hamming-coded balise and speed-code
telegram. A board loads the zone controller's half of the protocol (wire_zc: report decoding, command encoding, zone
topics) through `wire.__getattr__` by its top-level name; here, where the firmware is a package, that half is
attached to `wire` once, so `wire.decode_report` means the same on both sides.
"""

from cbtc.firmware import telegram, wire, wire_zc
from cbtc.protocol import fast_wire

for _name, _value in list(vars(wire_zc).items()):
    if not _name.startswith("_") and _name not in vars(wire):
        setattr(wire, _name, _value)


def _no_attribute(name):
    raise AttributeError(f"module {wire.__name__!r} has no attribute {name!r}")


wire.__getattr__ = _no_attribute   # everything of wire_zc is attached; the board's lazy loader is not needed here


# the board's functions the controller runs faster, with the same results (fast_wire.py): virtual trains use them too
wire._C_HMAC = fast_wire.hmac_sha256
wire.seal = wire_zc.seal = fast_wire.sealer(wire)
wire.json = fast_wire.JSON
wire.dumps_compact = wire_zc.dumps_compact = fast_wire.dumps_compact
wire.encode_report = fast_wire.report_encoder(wire, wire_zc)
wire.encode_command = wire_zc.encode_command = fast_wire.command_encoder(wire, wire_zc)

__all__ = ["telegram", "wire"]

"""The wire protocol, one definition for boards and controller: the firmware's own modules, imported as a package.

`messages` declares every message's fields; `wire` is the board's half (sealing, checks, command decoding, report
encoding); `wire_zc` the zone's (report decoding, command encoding, zone topics, the mode and fault names);
`fast_wire` the controller's codec, the same bytes as those two for less work; `telegram` the Hamming-coded balise and
speed-code telegram.
"""

from cbtc.firmware import messages, telegram, wire, wire_zc
from cbtc.protocol import fast_wire

__all__ = ["fast_wire", "messages", "telegram", "wire", "wire_zc"]

"""Trains that watch the zones on their broker: a zone that runs another protocol version, layout or keys than these
trains is a mismatch, said in one line each, and the trains stop (cbtc trains).

A zone's retained info (cbtc.protocol.zone_info) counts only while its retained status says online: a zone that was
killed leaves its info behind, and its last will marks it offline.
"""

from cbtc.bus.client import ONLINE
from cbtc.protocol import wire, zone_info


class ZoneMatch:
    def __init__(self, bus, layout, keys, key_source, on_mismatch):
        """Watch the zones on `bus`; call `on_mismatch()` once when an online zone does not match `layout` and `keys`
        ({train id: key}, from `key_source`); `problems` then holds the sentences."""
        self.layout_name = layout.name
        self.layout_digest = layout.digest()
        self.keys = keys
        self.key_source = key_source
        self.on_mismatch = on_mismatch
        self.problems = []
        self._online = {}
        self._info = {}
        bus.subscribe(zone_info.STATUS_FILTER, self._status)
        bus.subscribe(zone_info.INFO_FILTER, self._information)

    def _status(self, topic, payload):
        self._online[topic.split("/")[2]] = bytes(payload) == ONLINE
        self._check()

    def _information(self, topic, payload):
        zone = topic.split("/")[2]
        if not payload:   # cleared by a zone that stopped
            self._info.pop(zone, None)
            return
        try:
            self._info[zone] = zone_info.decode_info(topic, payload)
        except wire.WireError as exc:
            self._info[zone] = {"error": exc.reason}
        self._check()

    def _check(self):
        if self.problems:
            return
        for zone, info in sorted(self._info.items()):
            if not self._online.get(zone):
                continue
            if "error" in info:
                self.problems = [f"zone {zone}'s information is not this version's ({info['error']}): run the zone "
                                 f"and the trains from one install of the same version"]
            else:
                self.problems = zone_info.mismatches(info, self.layout_name, self.layout_digest, self.keys,
                                                     self.key_source)
            if self.problems:
                self.on_mismatch()
                return

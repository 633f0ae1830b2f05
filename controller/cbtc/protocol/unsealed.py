"""A report whose seal the zone cannot check: a board under an id it holds no key for.

Read only to learn where something on the track is (cbtc.zone.obstacles), never to grant anything. Controller side
alone: a board never reads another's reports, so this stays out of the firmware's protocol modules.
"""

from cbtc.protocol import fast_wire, wire, wire_zc


def peek_report(topic, payload):
    """The report dict of a payload whose seal this side cannot check (a board it holds no key for), validated as
    decode_report does otherwise: taken only as where something on the track is, never to grant anything;
    WireError with the reason otherwise."""
    if not isinstance(payload, (bytes, bytearray)) or len(payload) > wire.MAX_PAYLOAD:
        raise wire.WireError("payload on %s is not bytes of at most %d" % (topic, wire.MAX_PAYLOAD))
    payload = bytes(payload)
    cut = payload.rfind(b"#")
    try:
        msg = fast_wire.loads(payload[:cut] if cut >= 0 else payload)
    except ValueError:
        raise wire.WireError("payload on %s is not JSON" % topic) from None
    if not isinstance(msg, dict) or type(msg.get("v")) is not int or msg.get("v") != wire.VERSION \
            or msg.get("k") != "rep" or msg.get("id") != wire.train_id_of(topic):
        raise wire.WireError("payload on %s is not a report of version %d for its train" % (topic, wire.VERSION))
    wire.check_ints(msg, wire_zc.REPORT_INTS, topic)
    return wire_zc.check_report(msg, topic)

"""A train's report off the wire: authenticated with its key and checked, or refused with what to do about it."""

from cbtc.protocol import fast_wire, wire


def decoded_report(state, payload, key_source):
    """(report, None) for `state`'s train, or (None, (klass, reason, advice)) saying why not: a wrong key
    (`key_source` names where the zone's comes from), another firmware version, an invalid message."""
    try:
        return fast_wire.decode_report(state.setup.key, wire.topic_report(state.train_id), payload), None
    except wire.AuthError:
        return None, ("wrong key", "its reports fail authentication",
                      f"the zone's key is from {key_source}: flash the board with it (cbtc flash --keys FILE) or "
                      f"give the zone the board's")
    except wire.WireError as exc:
        other = " names version " in exc.reason   # a board of another version (the key matched): flash it
        return None, ("other version" if other else "invalid report", exc.reason,
                      f"flash the board with this version's firmware (cbtc flash), which speaks version "
                      f"{wire.VERSION}" if other else "")

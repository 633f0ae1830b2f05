"""docs/protocol.md's field tables, written from the message table (messages.py): tests/test_messages.py holds the
document to them, and `python -m cbtc.protocol.message_docs` prints them to paste in after a change."""

from cbtc.firmware import messages, wire

_POWERS = {2 ** 31 - 1: "2^31-1", -(2 ** 31 - 1): "-(2^31-1)", 2 ** 30 - 1: "2^30-1"}


def bound_text(value: int) -> str:
    """An integer bound as the document writes it: 2^30-1 and 2^31-1 by name."""
    return _POWERS.get(value, str(value))


def range_text(lo: int, hi: int) -> str:
    return f"[{bound_text(lo)}, {bound_text(hi)}]"


def _specs_text(specs: tuple) -> str:
    return "; ".join(f"{specs[i]} {range_text(specs[i + 1], specs[i + 2])}" for i in range(0, len(specs), 3))


def _ticked(names) -> str:
    return ", ".join(f"`{name}`" for name in names)


def _type_and_range(kind: str, name: str, bounds, message_kind: str) -> tuple:
    if kind == "const":
        return ("int", str(bounds)) if bounds is not None else ("str", f'`"{message_kind}"`')
    if kind == "id":
        return "str", f"1-{wire._ID_MAX_LEN} characters"
    if kind == "int":
        return "int", range_text(*bounds)
    if kind == "int?":
        return "int or absent", range_text(*bounds) + f"; absent: {bounds[0]}"
    if kind == "choice":
        return "str", "one of " + _ticked(bounds)
    if kind == "names":
        return "list of str", "each one of " + _ticked(bounds)
    if kind in ("list", "list?"):
        return "null or [" + ", ".join(bounds[::3]) + "]", _specs_text(bounds)
    if kind == "tags":
        items = "uid, " + ", ".join(bounds[::3])
        uids = "uid %d, %d or %d hex digits (a 4, 7 or 10-byte MFRC522 uid)" % messages.UID_HEX_LENGTHS
        return (f"list of [{items}] or [{items}, data]",
                f"at most {wire.MAX_TAGS}; {uids}; {_specs_text(bounds)}; data 32 hex digits")
    if kind == "text":
        return "str", f"1-{bounds} characters"
    if kind == "hex":
        return "str", f"{bounds} hex digits"
    if kind == "checks":
        return "object", f"{{train id: {bounds} hex digits}}"
    raise ValueError(f"field {name!r} has the unknown kind {kind!r}")


def markdown(message: tuple) -> str:
    """The markdown table of a message's fields, its header first."""
    rows = ["| field | type | range | unit | meaning |", "|---|---|---|---|---|"]
    for name, kind, bounds, unit, meaning in messages.HEADER + message[1]:
        type_text, bounds_text = _type_and_range(kind, name, bounds, message[0])
        rows.append(f"| `{name}` | {type_text} | {bounds_text} | {unit or '-'} | {meaning} |")
    return "\n".join(rows)


if __name__ == "__main__":
    for title, message in (("Report", messages.REPORT), ("Command", messages.COMMAND),
                           ("Zone information", messages.ZONE_INFO)):
        print(f"### {title}\n\n{markdown(message)}\n")

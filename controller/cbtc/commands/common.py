"""Helpers shared by sub-commands: printing tables and JSON."""

import json


def print_json(data) -> None:
    print(json.dumps(data, indent=2, sort_keys=True))


def format_table(rows, columns):
    """A plain-text table of dict rows; `columns` is a list of (key, header)."""
    cells = [[header for _key, header in columns]]
    for row in rows:
        cells.append(["-" if row.get(key) is None else str(row.get(key)) for key, _header in columns])
    widths = [max(len(r[c]) for r in cells) for c in range(len(columns))]
    lines = ["  ".join(cell.rjust(w) for cell, w in zip(r, widths)) for r in cells]
    lines.insert(1, "  ".join("-" * w for w in widths))
    return "\n".join(lines)

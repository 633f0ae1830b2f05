"""`cbtc balise`: the telegrams that make RFID tags into balises carrying their own position (Hill's telegram coding).

`cbtc balise image --layout FILE` prints, for every tag of a layout, the 16 bytes to write into its data pages 4-7
(NTAG213/215 or MIFARE Ultralight sticker); `cbtc balise read HEX` decodes what a board reported.
"""

from cbtc.commands import arg_types
from cbtc.commands.common import format_table, print_json
from cbtc.errors import CbtcError

EXAMPLES = (
    "cbtc balise image --layout lego_oval",
)


def register(sub):
    p = sub.add_parser("balise", help="write telegram images for balise tags, and decode tag data",
                       description=__doc__)
    verbs = p.add_subparsers(dest="verb", metavar="VERB")
    verbs.required = True
    image = verbs.add_parser("image", help="print the 16 data bytes to write into each tag of a layout")
    image.add_argument("--layout", type=arg_types.layout, default="itb_square",
                       help="layout whose tags to write telegrams for (default itb_square)")
    image.add_argument("--json", action="store_true", help="print the telegrams as JSON")
    image.set_defaults(func=run_image)
    read = verbs.add_parser("read", help="decode a tag's data as a board reports it (32 hex digits)")
    read.add_argument("data", metavar="HEX")
    read.add_argument("--json", action="store_true", help="print the decoded telegram as JSON")
    read.set_defaults(func=run_read)


def run_image(args):
    from cbtc.layout_files import load_layout
    from cbtc.railway import balise

    layout = load_layout(args.layout)
    rows = []
    for i, tag in enumerate(layout.tags):
        data = balise.image(i + 1, tag.s_m).hex()
        rows.append({"uid": tag.uid, "tag_id": i + 1, "s_m": round(tag.s_m, 4),
                     "pages_4_to_7": " ".join(data[k:k + 8] for k in range(0, 32, 8))})
    if args.json:
        print_json({"layout": layout.name, "tags": rows})
        return 0
    print(f"balise telegrams for {layout.name}: write each line's 16 bytes into pages 4-7 of the tag with that uid")
    print(format_table(rows, [("uid", "uid"), ("tag_id", "id"), ("s_m", "s m"), ("pages_4_to_7", "pages 4-7 (hex)")]))
    return 0


def run_read(args):
    from cbtc.railway import balise

    try:
        tag_id, s_m, status = balise.read(args.data.replace(" ", ""))
    except ValueError as exc:
        raise CbtcError(f"{exc}: give the 32 hex digits the board reported") from None
    result = {"tag_id": tag_id, "s_m": s_m, "status": status}
    if args.json:
        print_json(result)
    elif s_m is None:
        print("telegram rejected: two or more bits are wrong (read the tag again)")
    else:
        print(f"tag {tag_id} at s = {s_m:.3f} m ({status})")
    return 0 if s_m is not None else 1

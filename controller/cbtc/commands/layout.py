"""`cbtc layout show|list`: what a layout holds, and a drawing of it."""


from cbtc.commands import arg_types
from cbtc.commands.common import format_table, print_json

EXAMPLES = (
    "cbtc layout list",
    "cbtc layout show lego_oval --plot oval.png",
)


def register(sub):
    p = sub.add_parser("layout", help="list or show the track layouts", description=__doc__)
    verbs = p.add_subparsers(dest="verb", metavar="VERB")
    verbs.required = True
    show = verbs.add_parser("show", help="print a layout's length, stations, tags and blocks; draw it")
    show.add_argument("layout", help="YAML file or packaged name (see `cbtc layout list`)")
    show.add_argument("--plot", "--png", dest="plot", metavar="PNG", type=arg_types.plot_file,
                      help="draw the layout to this PNG (--png: the same, the older name)")
    show.add_argument("--json", action="store_true", help="print the description as JSON")
    show.set_defaults(func=run_show)
    listing = verbs.add_parser("list", help="list the packaged layouts")
    listing.set_defaults(func=run_list)


def describe(layout) -> dict:
    """A layout as plain data: lengths and positions in metres, rounded to 0.1 mm."""
    import numpy as np

    tag_xy = layout.xy(np.array([t.s_m for t in layout.tags])) if layout.tags else np.zeros((0, 2))
    return {
        "name": layout.name, "source": layout.source, "closed": layout.closed, "length_m": round(layout.length_m, 4),
        "segments": layout.segment_count,
        "stations": [{"name": s.name, "s_m": s.s_m, "window_m": s.window_m} for s in layout.stations],
        "tags": [{"uid": t.uid, "s_m": t.s_m, "x_m": round(float(x), 4), "y_m": round(float(y), 4)}
                 for t, (x, y) in zip(layout.tags, tag_xy)],
        "blocks": [{"name": b.name, "start_m": round(b.start_m, 4), "end_m": round(b.end_m, 4),
                    "length_m": round(_block_length_m(layout, b), 4)} for b in layout.blocks],
    }


def _block_length_m(layout, block):
    if layout.closed:
        return layout.ahead_m(block.start_m, block.end_m) or layout.length_m
    return block.end_m - block.start_m


def run_show(args):
    from cbtc.layout_files import load_layout

    layout = load_layout(args.layout)
    info = describe(layout)
    if args.plot:
        draw_png(layout, args.plot)
    if args.json:
        print_json(info)
        return 0
    print(f"{info['name']} ({info['source']})")
    count = info["segments"]
    print(f"{'closed loop' if info['closed'] else 'open line'}, {info['length_m']} m, {count} "
          f"segment{'' if count == 1 else 's'}")
    if info["stations"]:
        print("\nstations:")
        print(format_table(info["stations"], [("name", "name"), ("s_m", "s m"), ("window_m", "window m")]))
    if info["tags"]:
        print("\nRFID tags:")
        print(format_table(info["tags"], [("uid", "uid"), ("s_m", "s m"), ("x_m", "x m"), ("y_m", "y m")]))
    if info["blocks"]:
        print("\nfixed blocks:")
        print(format_table(info["blocks"], [("name", "name"), ("start_m", "start m"), ("end_m", "end m"),
                                            ("length_m", "length m")]))
    if args.plot:
        print(f"\ndrawing: {args.plot}")
    return 0


def run_list(args):
    from cbtc.layout_files import layout_names, load_layout

    rows = []
    for name in layout_names():
        layout = load_layout(name)
        rows.append({"name": name, "kind": "loop" if layout.closed else "line", "length_m": f"{layout.length_m:.3f}",
                     "segments": layout.segment_count, "stations": len(layout.stations), "tags": len(layout.tags),
                     "blocks": len(layout.blocks)})
    print(format_table(rows, [("name", "name"), ("kind", "kind"), ("length_m", "length m"), ("segments", "segments"),
                              ("stations", "stations"), ("tags", "tags"), ("blocks", "blocks")]))
    return 0


def draw_png(layout, path):
    """Draw the track centre line, stations, tags, block boundaries and IPS beacons to a PNG; returns `path`."""
    import matplotlib
    import numpy as np

    from cbtc.railway.ips_frame import ips_to_track
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    s = np.linspace(0.0, layout.length_m, 2000, endpoint=True)
    xy = layout.xy(s)
    fig, ax = plt.subplots(figsize=(7, 7))
    ax.plot(xy[:, 0], xy[:, 1], color="0.35", lw=3, zorder=1, label="track centre line")
    x0, y0, h0 = layout.pose(0.0)
    ax.annotate("", (x0 + 0.12 * np.cos(h0), y0 + 0.12 * np.sin(h0)), (x0, y0),
                arrowprops={"arrowstyle": "->", "color": "black", "lw": 1.5}, zorder=4)
    ax.annotate("s=0", (x0, y0), textcoords="offset points", xytext=(4, 6), fontsize=8)
    size = float(np.ptp(xy, axis=0).max()) or 1.0
    for st in layout.stations:
        x, y, h = layout.pose(st.s_m)
        ax.plot(x, y, "s", color="tab:blue", ms=9, zorder=3)
        nx, ny = -np.sin(h), np.cos(h)   # left of the direction of travel, towards the inside of a left-hand loop
        ax.annotate(f"{st.name}\ns={st.s_m:.3f}", (x, y), (x + 0.09 * size * nx, y + 0.09 * size * ny),
                    color="tab:blue", fontsize=9, fontweight="bold", ha="center", va="center")
    for tag in layout.tags:
        x, y, h = layout.pose(tag.s_m)
        ax.plot(x, y, "o", color="tab:orange", ms=5, zorder=3)
        ax.annotate(tag.uid[-4:], (x, y), (x + 0.035 * size * np.sin(h), y - 0.035 * size * np.cos(h)),
                    fontsize=6, color="tab:orange", ha="center", va="center")
    for block in layout.blocks:
        x, y, h = layout.pose(block.start_m)
        dx, dy = -np.sin(h) * 0.03 * size, np.cos(h) * 0.03 * size
        ax.plot([x - dx, x + dx], [y - dy, y + dy], color="tab:red", lw=2, zorder=2)
        ax.annotate(block.name, (x - 1.6 * dx, y - 1.6 * dy), fontsize=7, color="tab:red", ha="center", va="center")
    for bx, by, bz in layout.ips.beacons:
        x, y = ips_to_track(bx, by, layout.ips)
        ax.plot(x, y, "^", color="tab:green", ms=9)
        ax.annotate(f"z={bz:g}", (x, y), textcoords="offset points", xytext=(6, 4), fontsize=7, color="tab:green")
    ax.plot([], [], "s", color="tab:blue", label="station (stop point)")
    ax.plot([], [], "o", color="tab:orange", label="RFID tag (uid tail)")
    ax.plot([], [], "-", color="tab:red", label="block boundary")
    if layout.ips.beacons:
        ax.plot([], [], "^", color="tab:green", label="IPS beacon")
    ax.set_aspect("equal", adjustable="datalim")
    ax.margins(0.08)
    ax.set_xlabel("x (m)")
    ax.set_ylabel("y (m)")
    ax.set_title(f"{layout.name}: {'loop' if layout.closed else 'line'}, {layout.length_m:.3f} m")
    ax.grid(True, alpha=0.3)
    ax.legend(loc="upper center", bbox_to_anchor=(0.5, -0.1), ncol=3, fontsize=8, frameon=False)
    fig.tight_layout()
    fig.savefig(path, dpi=100)
    plt.close(fig)
    return path

"""`cbtc layout show|list`: what a layout holds, and a drawing of it."""

import numpy as np

from ..layout import layout_names, load_layout
from .common import format_table, print_json


def register(sub):
    p = sub.add_parser("layout", help="show or list track layouts", description=__doc__)
    verbs = p.add_subparsers(dest="verb", metavar="VERB")
    verbs.required = True
    show = verbs.add_parser("show", help="print a layout's length, stations, tags and blocks; draw it")
    show.add_argument("layout", help="YAML file or packaged name (see `cbtc layout list`)")
    show.add_argument("--png", metavar="OUT", help="draw the layout to this PNG")
    show.add_argument("--json", action="store_true")
    show.set_defaults(func=run_show)
    listing = verbs.add_parser("list", help="the packaged layouts")
    listing.set_defaults(func=run_list)


def describe(layout) -> dict:
    return {
        "name": layout.name, "source": layout.source, "closed": layout.closed, "length_m": round(layout.length_m, 4),
        "stations": [{"name": s.name, "s_m": s.s_m, "window_m": s.window_m} for s in layout.stations],
        "tags": [{"uid": t.uid, "s_m": t.s_m, "x_m": round(float(layout.xy(t.s_m)[0]), 4),
                  "y_m": round(float(layout.xy(t.s_m)[1]), 4)} for t in layout.tags],
        "blocks": [{"name": b.name, "start_m": round(b.start_m, 4), "end_m": round(b.end_m, 4),
                    "length_m": round(layout.ahead_m(b.start_m, b.end_m) or layout.length_m, 4)} for b in layout.blocks],
    }


def run_show(args):
    layout = load_layout(args.layout)
    info = describe(layout)
    if args.png:
        draw_png(layout, args.png)
    if args.json:
        print_json(info)
        return 0
    print(f"{info['name']} ({info['source']}): {'closed loop' if info['closed'] else 'open line'}, "
          f"{info['length_m']} m")
    print("\nstations:")
    print(format_table(info["stations"], [("name", "name"), ("s_m", "s m"), ("window_m", "window m")]))
    print("\nRFID tags:")
    print(format_table(info["tags"], [("uid", "uid"), ("s_m", "s m"), ("x_m", "x m"), ("y_m", "y m")]))
    if info["blocks"]:
        print("\nfixed blocks:")
        print(format_table(info["blocks"], [("name", "name"), ("start_m", "start m"), ("end_m", "end m"),
                                            ("length_m", "length m")]))
    if args.png:
        print(f"\ndrawing: {args.png}")
    return 0


def run_list(args):
    for name in layout_names():
        layout = load_layout(name)
        print(f"{name:16s} {'loop' if layout.closed else 'line':5s} {layout.length_m:7.3f} m  "
              f"{len(layout.stations)} stations, {len(layout.tags)} tags, {len(layout.blocks)} blocks")
    return 0


def draw_png(layout, path):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    s = np.linspace(0.0, layout.length_m, 2000, endpoint=not layout.closed)
    xy = layout.xy(s)
    fig, ax = plt.subplots(figsize=(7, 7))
    ax.plot(xy[:, 0], xy[:, 1], color="0.3", lw=3, label="track centre line")
    start = layout.xy(0.0)
    ax.annotate("s=0", start, textcoords="offset points", xytext=(4, -12), fontsize=8)
    for st in layout.stations:
        x, y, h = layout.pose(st.s_m)
        ax.plot(x, y, "s", color="tab:blue", ms=9)
        ax.annotate(st.name, (x, y), textcoords="offset points", xytext=(-10 * np.sin(h) * 2, 10 * np.cos(h) * 2),
                    color="tab:blue", fontsize=10, fontweight="bold", ha="center")
    for tag in layout.tags:
        x, y = layout.xy(tag.s_m)
        ax.plot(x, y, "o", color="tab:orange", ms=5)
        ax.annotate(tag.uid[-4:], (x, y), textcoords="offset points", xytext=(3, 3), fontsize=6, color="tab:orange")
    for block in layout.blocks:
        x, y, h = layout.pose(block.start_m)
        dx, dy = -np.sin(h) * 0.06, np.cos(h) * 0.06
        ax.plot([x - dx, x + dx], [y - dy, y + dy], color="tab:red", lw=2)
        ax.annotate(block.name, (x + dx, y + dy), fontsize=7, color="tab:red")
    from ..ips_frame import ips_to_track
    for bx, by, _bz in layout.ips.beacons:
        x, y = ips_to_track(bx, by, layout.ips)
        ax.plot(x, y, "^", color="tab:green", ms=8)
    ax.plot([], [], "s", color="tab:blue", label="station")
    ax.plot([], [], "o", color="tab:orange", label="RFID tag")
    ax.plot([], [], "-", color="tab:red", label="block boundary")
    if layout.ips.beacons:
        ax.plot([], [], "^", color="tab:green", label="IPS beacon")
    ax.set_aspect("equal")
    ax.set_xlabel("x (m)")
    ax.set_ylabel("y (m)")
    ax.set_title(f"{layout.name}: {layout.length_m:.3f} m, {'loop' if layout.closed else 'line'}")
    ax.grid(True, alpha=0.3)
    ax.legend(loc="best", fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=100)
    plt.close(fig)
    return path

"""`cbtc layout show|list`: what a layout holds, and a drawing of it."""


from cbtc.commands import arg_types
from cbtc.commands.common import format_table, print_json

EXAMPLES = (
    "cbtc layout list",
    "cbtc layout show lego_oval --plot oval.png",
    "cbtc layout show lego_passing_loop --plot passing_loop.png",
)


def register(sub):
    p = sub.add_parser("layout", help="list or show the track layouts", description=__doc__)
    verbs = p.add_subparsers(dest="verb", metavar="VERB")
    verbs.required = True
    show = verbs.add_parser("show", help="print a layout's length, stations, tags and blocks (a network's sections "
                                         "and switches); draw it")
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

    if layout.is_network:
        return describe_network(layout)
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


def _end_name(graph, end):
    """The file's name of a graph end: `main.start`, `W1.straight` (a heel) or `W1.toe`."""
    section = graph.sections[end[0]]
    if section.switch:
        return f"{section.switch}.toe" if end[1] == "start" else section.name
    return f"{end[0]}.{end[1]}"


def _joined_to(graph, end):
    names = sorted({_end_name(graph, e) for e in graph.across(end)})
    return ", ".join(names) or "buffer stop"


def describe_network(layout) -> dict:
    """A track network as plain data: sections, switches with what each leg joins, stations and tags."""
    graph = layout.graph
    sections = [{"name": s.name, "length_m": round(s.length_m, 4), "switch": s.switch,
                 "start_joins": _joined_to(graph, (s.name, "start")), "end_joins": _joined_to(graph, (s.name, "end"))}
                for s in graph.sections.values() if not s.switch]
    switches = []
    for w in graph.switches.values():
        toe = (w.leg_section("straight"), "start")
        x, y = (round(v, 4) + 0.0 for v in w.toe_xy_m)   # + 0.0: -0.0 is 0.0
        switches.append({"id": w.id, "hand": w.hand, "x_m": x, "y_m": y,
                         "toe_joins": _joined_to(graph, toe),
                         "straight_joins": _joined_to(graph, (w.leg_section("straight"), "end")),
                         "diverging_joins": _joined_to(graph, (w.leg_section("diverging"), "end"))})
    tags = []
    for t in layout.tags:
        x, y = layout.xy_m(t.section, t.offset_m)
        tags.append({"uid": t.uid, "section": t.section, "offset_m": t.offset_m, "x_m": round(x, 4) + 0.0,
                     "y_m": round(y, 4) + 0.0})
    crossings = sorted({s.crossing for s in graph.sections.values() if s.crossing})
    return {"name": layout.name, "source": layout.source, "kind": "network", "length_m": round(layout.length_m, 4),
            "sections": sections, "switches": switches, "crossings": crossings,
            "stations": [{"name": s.name, "section": s.section, "offset_m": s.offset_m,
                          "back_offset_m": round(s.back_offset_m, 4), "window_m": s.window_m} for s in layout.stations],
            "tags": tags}


def _show_network(info):
    print(f"{info['name']} ({info['source']})")
    print(f"track network, {info['length_m']} m of track, {len(info['sections'])} sections, "
          f"{len(info['switches'])} switches" + (f", crossings {', '.join(info['crossings'])} (tracks a and b)"
                                                 if info["crossings"] else ""))
    print("\nsections:")
    print(format_table(info["sections"], [("name", "name"), ("length_m", "length m"), ("start_joins", "start joins"),
                                          ("end_joins", "end joins")]))
    if info["switches"]:
        print("\nswitches:")
        print(format_table(info["switches"], [("id", "id"), ("hand", "hand"), ("x_m", "toe x m"), ("y_m", "toe y m"),
                                              ("toe_joins", "toe joins"), ("straight_joins", "straight leg joins"),
                                              ("diverging_joins", "diverging leg joins")]))
    if info["stations"]:
        print("\nstations:")
        print(format_table(info["stations"], [("name", "name"), ("section", "section"), ("offset_m", "offset m"),
                                              ("back_offset_m", "backwards m"), ("window_m", "window m")]))
    if info["tags"]:
        print("\nRFID tags:")
        print(format_table(info["tags"], [("uid", "uid"), ("section", "section"), ("offset_m", "offset m"),
                                          ("x_m", "x m"), ("y_m", "y m")]))


def _block_length_m(layout, block):
    if layout.closed:
        return layout.ahead_m(block.start_m, block.end_m) or layout.length_m
    return block.end_m - block.start_m


def run_show(args):
    from cbtc.layout_files import load_track

    layout = load_track(args.layout)
    info = describe(layout)
    if args.plot:
        (draw_network_png if layout.is_network else draw_png)(layout, args.plot)
    if args.json:
        print_json(info)
        return 0
    if layout.is_network:
        _show_network(info)
        if args.plot:
            print(f"\ndrawing: {args.plot}")
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
    from cbtc.layout_files import layout_names, load_track

    rows = []
    for name in layout_names():
        layout = load_track(name)
        if layout.is_network:
            rows.append({"name": name, "kind": "network", "length_m": f"{layout.length_m:.3f}",
                         "segments": sum(len(s.path.segments) for s in layout.graph.sections.values()),
                         "switches": len(layout.graph.switches), "stations": len(layout.stations),
                         "tags": len(layout.tags), "blocks": "-"})
            continue
        rows.append({"name": name, "kind": "loop" if layout.closed else "line", "length_m": f"{layout.length_m:.3f}",
                     "segments": layout.segment_count, "switches": 0, "stations": len(layout.stations),
                     "tags": len(layout.tags), "blocks": len(layout.blocks)})
    print(format_table(rows, [("name", "name"), ("kind", "kind"), ("length_m", "length m"), ("segments", "segments"),
                              ("switches", "switches"), ("stations", "stations"), ("tags", "tags"),
                              ("blocks", "blocks")]))
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


def _draw_switches(ax, graph):
    """Each switch: a diamond at its toe with its id, its legs marked S (straight) and D (diverging); each crossing:
    a cross at its middle with its id."""
    for w in graph.switches.values():
        x, y = w.toe_xy_m
        ax.plot(x, y, "D", color="black", ms=6, zorder=4)
        ax.annotate(w.id, (x, y), textcoords="offset points", xytext=(-4, -12), fontsize=9, fontweight="bold")
        for leg, mark in (("straight", "S"), ("diverging", "D")):
            lx, ly = graph.sections[w.leg_section(leg)].path.xy_m(graph.sections[w.leg_section(leg)].length_m * 0.7)
            ax.annotate(mark, (lx, ly), fontsize=7, ha="center", va="center", zorder=5,
                        bbox={"boxstyle": "circle,pad=0.15", "fc": "white", "ec": "0.5", "lw": 0.5})
    for name in sorted({s.crossing for s in graph.sections.values() if s.crossing}):
        x, y = graph.sections[f"{name}.a"].path.xy_m(graph.sections[f"{name}.a"].length_m / 2)
        ax.plot(x, y, "X", color="black", ms=9, zorder=4)
        ax.annotate(name, (x, y), textcoords="offset points", xytext=(6, -12), fontsize=9, fontweight="bold")


def draw_network_png(layout, path):
    """Draw a network's sections (each named), its switches (id at the toe, legs marked S and D), stations and tags
    to a PNG; returns `path`."""
    import matplotlib
    import numpy as np

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    graph = layout.graph
    fig, ax = plt.subplots(figsize=(9, 6))
    xy_all = []
    for section in graph.sections.values():
        s = np.linspace(0.0, section.length_m, max(2, int(section.length_m * 200)))
        xy = section.path.xy(s)
        xy_all.append(xy)
        if section.switch:
            colour = "tab:purple" if section.leg == "diverging" else "tab:brown"
            ax.plot(xy[:, 0], xy[:, 1], color=colour, lw=3, zorder=2)
        else:
            ax.plot(xy[:, 0], xy[:, 1], color="0.35", lw=3, zorder=1)
            mx, my, h = section.path.pose(section.length_m / 2)
            ax.annotate(section.name, (mx, my), (mx - 0.06 * np.sin(h), my + 0.06 * np.cos(h)), fontsize=7,
                        color="0.25", ha="center", va="center")
    size = float(np.ptp(np.concatenate(xy_all), axis=0).max()) or 1.0
    _draw_switches(ax, graph)
    for node in graph.nodes:
        if not node.side_b:
            ax.plot(*node.xy_m, "|", color="black", ms=14, mew=3, zorder=4)
    track_xy = np.concatenate(xy_all)
    for st in layout.stations:   # each name on the side of its track with the more room
        x, y, h = graph.sections[st.section].path.pose(st.offset_m)
        sides = [(x + k * 0.05 * size * -np.sin(h), y + k * 0.05 * size * np.cos(h)) for k in (1.0, -1.0)]
        label = max(sides, key=lambda p: np.min(np.hypot(track_xy[:, 0] - p[0], track_xy[:, 1] - p[1])))
        ax.plot(x, y, "s", color="tab:blue", ms=8, zorder=3)
        ax.annotate(st.name, (x, y), label, color="tab:blue", fontsize=8, fontweight="bold", ha="center",
                    va="center")
    for tag in layout.tags:
        x, y = layout.xy_m(tag.section, tag.offset_m)
        ax.plot(x, y, "o", color="tab:orange", ms=4, zorder=3)
    ax.plot([], [], "-", color="0.35", lw=3, label="section (named)")
    ax.plot([], [], "-", color="tab:brown", lw=3, label="switch, straight leg (S)")
    ax.plot([], [], "-", color="tab:purple", lw=3, label="switch, diverging leg (D)")
    ax.plot([], [], "D", color="black", label="switch toe (id)")
    if any(s.crossing for s in graph.sections.values()):
        ax.plot([], [], "X", color="black", label="crossing (id)")
    ax.plot([], [], "|", color="black", mew=3, ms=10, label="buffer stop")
    ax.plot([], [], "s", color="tab:blue", label="station (stop point)")
    ax.plot([], [], "o", color="tab:orange", label="RFID tag")
    ax.set_aspect("equal", adjustable="datalim")
    ax.margins(0.08)
    ax.set_xlabel("x (m)")
    ax.set_ylabel("y (m)")
    ax.set_title(f"{layout.name}: track network, {layout.length_m:.3f} m, {len(graph.switches)} switches")
    ax.grid(True, alpha=0.3)
    ax.legend(loc="upper center", bbox_to_anchor=(0.5, -0.12), ncol=4, fontsize=8, frameon=False)
    fig.tight_layout()
    fig.savefig(path, dpi=100)
    plt.close(fig)
    return path

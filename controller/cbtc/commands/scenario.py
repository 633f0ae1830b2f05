"""`cbtc scenario list|show`: the shipped scenario files, and what a scenario file sets up (checked as it is read)."""

from cbtc.commands import arg_types
from cbtc.commands.common import format_table, print_json

EXAMPLES = (
    "cbtc scenario list",
    "cbtc scenario show paper_itb",
)


def register(sub):
    p = sub.add_parser("scenario", help="list the shipped scenarios, or check and show a scenario file",
                       description=__doc__)
    verbs = p.add_subparsers(dest="verb", metavar="VERB")
    verbs.required = True
    show = verbs.add_parser("show", help="check a scenario file and print its trains, stops and faults")
    show.add_argument("scenario", type=arg_types.scenario, help="YAML file or packaged name (cbtc scenario list)")
    show.add_argument("--json", action="store_true", help="print the description as JSON")
    show.set_defaults(func=run_show)
    listing = verbs.add_parser("list", help="list the packaged scenarios")
    listing.set_defaults(func=run_list)


def describe(config) -> dict:
    return {
        "name": config.name, "layout": config.layout.name, "seed": config.seed, "duration_s": config.duration_s,
        "laps": config.laps, "policy": config.policy, "estimator": config.estimator,
        "dwell_s": list(config.dwell_s),
        "trains": [{"id": t.train_id, "start_m": round(t.s0_m, 4), "stops": list(t.stops),
                    "dwell_s": list(t.dwell_s or config.dwell_s), "length_m": t.profile.length_m,
                    "v_max_mps": t.profile.v_max_mps, "accel_max_mps2": t.profile.accel_max_mps2,
                    "beta_s_mps2": t.profile.beta_s_mps2} for t in config.trains],
        "faults": [str(f) for f in config.faults],
        "reference": config.reference,
    }


def run_show(args):
    info = describe(args.scenario)
    if args.json:
        print_json(info)
        return 0
    laps = f", {info['laps']} laps at most" if info["laps"] else ""
    print(f"scenario {info['name']}: layout {info['layout']}, seed {info['seed']}, {info['duration_s']:g} s{laps}, "
          f"{info['policy']}, {info['estimator']}")
    rows = [{**t, "stops": ",".join(t["stops"]) or "-", "dwell_s": "-".join(f"{d:g}" for d in t["dwell_s"])}
            for t in info["trains"]]
    print(format_table(rows, [("id", "train"), ("start_m", "start m"), ("stops", "stops"), ("dwell_s", "dwell s"),
                              ("length_m", "length m"), ("v_max_mps", "v max m/s"),
                              ("accel_max_mps2", "accel m/s2"), ("beta_s_mps2", "brake m/s2")]))
    for fault in info["faults"]:
        print(f"fault: {fault}")
    if info["reference"]:
        ref = dict(info["reference"])
        print(f"reference ({ref.pop('source')}): " + ", ".join(f"{k} {v:g}" for k, v in ref.items()))
    return 0


def run_list(_args):
    import textwrap

    from cbtc.scenario_files import resolve_scenario, scenario_names

    for name in scenario_names():
        words = []
        with open(resolve_scenario(name), encoding="utf-8") as fh:
            for line in fh:   # the comment the file opens with, whole: its sentences are not cut
                if not line.startswith("#"):
                    break
                words.append(line.lstrip("# ").strip())
        text = _first_sentence(" ".join(w for w in words if w))
        # a `command` in it is kept on one line: its spaces do not break
        kept = "`".join(part.replace(" ", "\u00a0") if i % 2 else part for i, part in enumerate(text.split("`")))
        print(textwrap.fill(kept, 118, initial_indent=f"{name:20s} ", subsequent_indent=" " * 21,
                            break_on_hyphens=False).replace("\u00a0", " "))
    return 0


def _first_sentence(text: str) -> str:
    """`text` to the end of its first sentence (a full stop outside `code` followed by a space, or its end)."""
    ticks = 0
    for i, ch in enumerate(text):
        ticks += ch == "`"
        if ch == "." and ticks % 2 == 0 and text[i + 1:i + 2] in (" ", ""):
            return text[:i + 1]
    return text

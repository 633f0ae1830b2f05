"""`cbtc sim`: any number of virtual trains on any layout, each following the one ahead."""


from cbtc.authority.policy import MOVING_BLOCK, policy_names
from cbtc.commands import arg_types
from cbtc.commands.common import SCENARIO_HELP, run_scenario_and_report, with_scenario
from cbtc.sim import faults

EXAMPLES = (
    "cbtc sim --layout lego_oval --trains 4 --duration 30",
    "cbtc sim --layout straight_test --trains 3 --duration 20 --policy fixed_block --blocks 6",
    "cbtc sim --scenario lego_oval_mixed --duration 30 --fault ips_blackout:train=F1,at_s=10 --plot run.png",
)


def register(sub):
    p = sub.add_parser("sim", description=__doc__,
                       help="simulate any trains on a layout or scenario, with faults, under either policy")
    p.add_argument("--scenario", type=arg_types.scenario, default=None, metavar="FILE", help=SCENARIO_HELP)
    p.add_argument("--layout", type=arg_types.layout, default=None,
                   help="layout file or packaged name (default: lego_oval)")
    p.add_argument("--trains", type=arg_types.train_count, default=None, help="number of trains (default: 3)")
    p.add_argument("--duration", type=arg_types.seconds, default=None,
                   help="simulated seconds (default: 120, or the scenario's)")
    p.add_argument("--seed", type=arg_types.seed, default=None, help="random seed (default: 0, or the scenario's)")
    p.add_argument("--policy", choices=policy_names(), default=None,
                   help="authority policy (default: moving_block, or the scenario's)")
    p.add_argument("--blocks", type=arg_types.whole(2), default=None, metavar="N",
                   help="fixed block: N equal blocks instead of the layout's own "
                        "(a loop needs more blocks than trains)")
    p.add_argument("--estimator", choices=("ukf", "odometry"), default=None,
                   help="position estimator (default: ukf, or the scenario's)")
    p.add_argument("--start-gap", type=arg_types.number(above=0.0, example="0.1"), default=None, metavar="M",
                   help="trains start one behind the other, M metres from a tail to the next head (several in one "
                        "fixed block); default: spread evenly along the layout")
    p.add_argument("--fault", action="append", default=[], metavar="NAME[:PARAM=VALUE,...]",
                   help="inject a fault into the simulated world (repeatable); names: "
                        + ", ".join(f"{name} ({', '.join(f'{k}={v}' for k, v in params.items())})"
                                    for name, (_what, params) in sorted(faults.FAULTS.items())))
    p.add_argument("--record", type=arg_types.output_file, default=None, metavar="FILE",
                   help="write every report the zone accepts as a JSON line (what cbtc calibrate reads)")
    p.add_argument("--json", action="store_true", help="print the result as JSON (no table, no bar)")
    p.add_argument("--plot", metavar="PNG", type=arg_types.plot_file, default="", help="write a distance-time plot")
    p.set_defaults(func=run)


DEFAULTS = {"layout": "lego_oval", "trains": 3, "duration": 120.0, "seed": 0, "policy": MOVING_BLOCK,
            "estimator": "ukf"}


def run(args):
    from cbtc.layout_files import load_track
    from cbtc.sim.runs import scenario_config, sim_config

    config = with_scenario(args, DEFAULTS, fixed=("layout", "trains", "start_gap"),
                           overrides={"seed": "seed", "duration": "duration_s", "policy": "policy",
                                      "estimator": "estimator"})
    if config is not None:
        config = scenario_config(config, blocks=args.blocks, fault_texts=args.fault)
        title = f"scenario {config.name}: {len(config.trains)} trains on {config.layout.name}, seed {config.seed}"
        return run_scenario_and_report(config, title, args)
    layout = load_track(args.layout)
    config = sim_config(layout, args.trains, args.seed, args.duration, args.policy, args.estimator, args.blocks,
                        args.fault, start_gap_m=args.start_gap)
    return run_scenario_and_report(config, f"{args.trains} trains on {layout.name}, seed {args.seed}", args)

"""`cbtc compare` on a track network: moving block against fixed blocks over the same trains, plans and
interlocking, in trains per hour and safety."""

from cbtc.authority.policy import FIXED_BLOCK, MOVING_BLOCK
from cbtc.commands.common import format_table, print_json
from cbtc.commands.progress_bar import shown, simulation_bar
from cbtc.errors import ConfigError
from cbtc.railway.network_layout import BLOCK_M

COLUMNS = [("policy", "system"), ("trains_per_hour", "trains/h"), ("stops_per_hour", "stops/h"),
           ("mean_lap_s", "round s"), ("collisions", "collisions"), ("authority_overruns", "overruns"),
           ("switch_violations", "switch violations"), ("plan_completed", "plans done"),
           ("emergency_trips", "trips")]
LOOP_ONLY = (("laps", "--laps"), ("blocks", "--blocks"), ("report_ms", "--report-ms"),
             ("follow_mps", "--follow-mps"), ("plot", "--plot"))
NETWORK_ONLY = (("trains", "--trains"), ("duration", "--duration"))


def network_base(args):
    """The network scenario `args` ask to compare on (--scenario on a network, or --layout naming one with --trains,
    --duration, --seed), or None for a single path; ConfigError for a flag that does not apply."""
    from cbtc.layout_files import load_track
    scenario = args.scenario
    layout = scenario.layout if scenario is not None else load_track(args.layout) if args.layout else None
    if not getattr(layout, "is_network", False):
        for name, flag in NETWORK_ONLY:
            if getattr(args, name, None) is not None:
                raise ConfigError(f"{flag}: only for a track network (e.g. --layout lego_passing_loop); the paper "
                                  "scenario has its two trains and runs --laps")
        return None
    for name, flag in LOOP_ONLY:
        if getattr(args, name, None) not in (None, "", []):
            raise ConfigError(f"{flag}: not on a track network ({layout.name}), whose blocks follow its sections and "
                              f"whose trains run --duration; leave {flag} out")
    if scenario is not None:
        if args.trains is not None:
            raise ConfigError(f"--trains: the scenario {scenario.name} sets the trains; leave --trains out")
        from dataclasses import replace
        changes = {k: v for k, v in (("seed", args.seed), ("duration_s", args.duration)) if v is not None}
        return replace(scenario, **changes), f"scenario {scenario.name} on {layout.name}"
    from cbtc.sim.runs import sim_config
    trains, duration_s, seed = args.trains or 4, args.duration or 600.0, 0 if args.seed is None else args.seed
    return sim_config(layout, trains, seed, duration_s), f"{trains} trains on {layout.name} for {duration_s:g} s"


def run_network(args, base, title) -> int:
    from cbtc.experiments.network_compare import run_network_systems
    with simulation_bar("compare", 2, shown(args)):
        result = run_network_systems(base, code_ber=args.code_ber)
    result = {"layout": base.layout.name, "seed": base.seed, "scenario": base.name, **result}
    if args.json:
        print_json(result)
        return 0
    systems = result["systems"]
    print(f"{title}, seed {base.seed}")
    print(format_table([systems[FIXED_BLOCK], systems[MOVING_BLOCK]], COLUMNS))
    gain = result["trains_per_hour_gain_pct"]
    print(f"moving block vs fixed block: {'n/a' if gain is None else f'{gain:+}'} % trains per hour (fixed blocks: a "
          f"signal at every switch's toe and heels and on plain track every {BLOCK_M:g} m at most)")
    return 0

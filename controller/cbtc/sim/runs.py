"""The configuration of one `cbtc sim` run from its command-line values: `cbtc sim` and `cbtc campaign` build it here,
so a campaign's printed command reproduces its run exactly."""

from dataclasses import replace

from cbtc.authority.policy import FIXED_BLOCK, MOVING_BLOCK
from cbtc.errors import ConfigError
from cbtc.layout_files import load_track
from cbtc.sim import faults
from cbtc.zone.config import queue_scenario
from cbtc.zone.factory import policy_class


def sim_config(layout, trains: int, seed: int, duration_s: float, policy: str = MOVING_BLOCK,
               estimator: str = "ukf", blocks=None, fault_texts=(), start_gap_m=None):
    """The ScenarioConfig of `cbtc sim --layout LAYOUT --trains N ... --fault F...` (`layout`: a name, a file or a
    loaded Layout); ConfigError for any bad value, before anything runs."""
    if isinstance(layout, str):
        layout = load_track(layout)
    _check_blocks(policy, blocks)
    options = {} if blocks is None else {"blocks": blocks}
    injected = tuple(faults.parse(text) for text in fault_texts)
    if getattr(layout, "is_network", False):
        if start_gap_m is not None or blocks is not None:
            raise ConfigError(f"layout {layout.name} is a track network: its trains are put down by the network's "
                              "own rule and its blocks follow its sections; drop --start-gap and --blocks")
        from cbtc.zone.network_config import network_queue
        config = network_queue(layout, trains, seed=seed, duration_s=duration_s, policy=policy,
                               estimator=estimator)
    else:
        config = queue_scenario(layout, trains, seed=seed, duration_s=duration_s, start_gap_m=start_gap_m,
                                policy=policy, estimator=estimator, policy_options=options)
    config.faults = injected
    return config


def scenario_config(scenario, seed: int = None, duration_s: float = None, blocks: int = None, fault_texts=()):
    """The ScenarioConfig of `cbtc sim --scenario FILE ...` (`scenario`: a file, a packaged name or a loaded config):
    the values given over the file's, `fault_texts` added to its faults; ConfigError for any bad value."""
    if isinstance(scenario, str):
        from cbtc.scenario_files import load_scenario
        scenario = load_scenario(scenario)
    changes = {name: value for name, value in (("seed", seed), ("duration_s", duration_s)) if value is not None}
    if blocks is not None:
        changes["policy_options"] = {**scenario.policy_options, "blocks": blocks}
    config = replace(scenario, **changes)
    _check_blocks(config.policy, config.policy_options.get("blocks"))
    return replace(config, faults=config.faults + tuple(faults.parse(text) for text in fault_texts))


def _check_blocks(policy, blocks):
    if blocks is not None and not policy_class(policy).uses_blocks:
        raise ConfigError(f"--blocks is for --policy {FIXED_BLOCK}: {policy_class(policy).title} has no blocks")

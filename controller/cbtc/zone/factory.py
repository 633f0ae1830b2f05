"""Builds a zone from a config: its policy, its estimators and the ZoneController itself, the same for a simulated
and a live run."""

from cbtc.authority.fixed_block import FixedBlockPolicy
from cbtc.authority.moving_block import MovingBlockPolicy
from cbtc.authority.policy import AuthorityPolicy, policy_names
from cbtc.errors import ConfigError
from cbtc.railway.network_layout import BLOCK_M
from cbtc.zone.config import ScenarioConfig
from cbtc.zone.controller import ZoneController
from cbtc.zone.train_state import TrainSetup

# the one place a policy is picked by its name (a scenario's `policy`, `--policy`)
POLICIES = {cls.name: cls for cls in (MovingBlockPolicy, FixedBlockPolicy)}
assert tuple(POLICIES) == policy_names()


def policy_class(name: str):
    """The AuthorityPolicy class called `name`; ConfigError naming the choices otherwise."""
    try:
        return POLICIES[name]
    except (KeyError, TypeError):
        raise ConfigError(f"unknown policy {name!r}: use {' or '.join(POLICIES)}") from None


def make_policy(config: ScenarioConfig) -> AuthorityPolicy:
    """The policy `config` names, with its options; ConfigError when its blocks do not fit the layout's trains."""
    cls = policy_class(config.policy)
    if not cls.uses_blocks:
        return cls(config.params, **config.policy_options)
    if getattr(config.layout, "is_network", False):
        if config.policy_options.get("blocks") is not None:
            raise ConfigError(f"{cls.title}: layout {config.layout.name} is a track network, whose blocks follow its "
                              f"sections (a signal at every switch's toe and heels, and every {BLOCK_M:g} m at most on "
                              "plain track): drop --blocks")
        return cls(config.params, **{"seed": config.seed, **config.policy_options})
    try:
        policy = cls(config.params, **{"seed": config.seed, **config.policy_options})
        blocks = policy.blocks(config.layout)
    except ValueError as exc:
        raise ConfigError(f"{cls.title}: {exc}") from None
    if config.layout.closed and len(blocks) <= len(config.trains):
        raise ConfigError(f"{cls.title}: {len(config.trains)} trains on the {len(blocks)} blocks of loop "
                          f"{config.layout.name} cannot move (each needs a clear block ahead): give more blocks "
                          f"than trains (--blocks), each well longer than a train and its margin, since a train "
                          f"across a block boundary holds two")
    return policy


def make_estimator_factory(name: str):
    if name == "ukf":
        from cbtc.estimation.ukf_estimator import UkfEstimator
        return UkfEstimator
    if name == "odometry":
        from cbtc.estimation.odometry_estimator import OdometryEstimator
        return OdometryEstimator
    raise ConfigError(f"unknown estimator {name!r}: use ukf or odometry")


def build_zone(config: ScenarioConfig, keys: dict, client, now_fn, zone_id: str = "zc1", seed: int = None,
               report_budget_hz: float = None) -> ZoneController:
    """The ZoneController of `config`'s trains on `client`, with keys {train_id: key}, reading time from `now_fn`."""
    setups = [TrainSetup(spec.train_id, keys[spec.train_id], spec.profile, tuple(spec.stops),
                         spec.dwell_s or config.dwell_s, spec.frame, spec.route, spec.legs)
              for spec in config.trains]
    return ZoneController(config.layout, setups, client, now_fn, make_policy(config), config.params,
                          make_estimator_factory(config.estimator), config.cycle_s, zone_id=zone_id,
                          seed=config.seed if seed is None else seed,
                          report_budget_hz=config.report_budget_hz if report_budget_hz is None else report_budget_hz)

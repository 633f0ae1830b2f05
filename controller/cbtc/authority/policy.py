"""What an authority policy is to the zone, the simulation and the plots: the one interface moving block and the
fixed-block baseline both meet, so nothing outside the factory (cbtc.zone.factory) asks which one it has.

A policy answers the frozen Authority of a train from a Situation (pure: values in, values out); it says what it
needs (track circuits: every train's span; fast reports of a followed train) and what it protects in truth (the point
no train may pass), which the simulation's monitor checks against the trains' true positions.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Protocol, runtime_checkable

if TYPE_CHECKING:   # the names alone: the command line reads policy_names() without loading the core
    from cbtc.authority.rules import AuthorityParams
    from cbtc.authority.values import Authority, Situation

MOVING_BLOCK = "moving_block"
FIXED_BLOCK = "fixed_block"   # the baseline every experiment compares moving block with


@runtime_checkable
class AuthorityPolicy(Protocol):
    name: str            # its name in a scenario, on the command line and in results (the factory's key)
    title: str           # its name in words, for tables and plots
    fast_reports: bool   # its authority rests on the train ahead's reports: a followed train is asked for fast ones
    needs_spans: bool    # it reads track circuits: the zone passes every train's span (Situation.spans)
    uses_blocks: bool    # it signals fixed blocks (a layout's, or a count of equal ones: `--blocks`)
    params: AuthorityParams

    def signal(self, sit: Situation) -> Situation:
        """`sit` as the train receives it through the wayside before its authority is made: the fixed-block speed
        code sent through the rails (a noisy telegram channel); moving block sends nothing."""

    def authority(self, sit: Situation) -> Authority:
        """The Authority of `sit.own`'s train: how far, how fast, and the reason that bounds it."""

    def blocks(self, layout) -> tuple:
        """The fixed blocks it signals on `layout` (railway.layout.Block); () for none."""

    def protected_m(self, layout, train_id: str, spans: list) -> float:
        """In truth: the distance (m) from `train_id`'s head to the point its authority protects, less the safety
        margin; `spans` lists (train_id, head_s, tail_s) of every train. Negative: an authority overrun."""

    def protected_all_m(self, layout, spans: list) -> list:
        """protected_m of every train of `spans`, in their order."""

    def stuck(self, layout, spans: list):
        """Why no train of `spans` can ever move under this policy (a sentence naming the fix), or None."""


def policy_names() -> tuple:
    """The names the factory builds a policy by: for a flag's choices and a scenario file's check."""
    return (MOVING_BLOCK, FIXED_BLOCK)

"""The policy interface: both policies meet cbtc.authority.policy.AuthorityPolicy, the factory is the one place a
policy is picked by its name, and nothing tests a policy's type."""

import os
import re

import pytest

from cbtc.authority.policy import FIXED_BLOCK, MOVING_BLOCK, AuthorityPolicy, policy_names
from cbtc.errors import ConfigError
from cbtc.layout_files import load_layout
from cbtc.zone.factory import POLICIES, policy_class

PACKAGE = os.path.join(os.path.dirname(os.path.dirname(os.path.abspath(__file__))), "controller", "cbtc")


def test_each_policy_meets_the_interface():
    layout = load_layout("lego_oval")
    spans = [("A", 1.0, 0.7), ("B", 2.5, 2.2)]
    for name, cls in POLICIES.items():
        policy = cls(blocks=8) if cls.uses_blocks else cls()
        assert isinstance(policy, AuthorityPolicy) and policy.name == name and policy.title
        assert len(policy.protected_all_m(layout, spans)) == 2
        assert policy.protected_all_m(layout, spans)[0] == policy.protected_m(layout, "A", spans)
        assert policy.stuck(layout, spans) is None
        assert bool(policy.blocks(layout)) == cls.uses_blocks
    assert tuple(POLICIES) == policy_names() == (MOVING_BLOCK, FIXED_BLOCK)
    with pytest.raises(ConfigError, match="unknown policy 'interlocked': use moving_block or fixed_block"):
        policy_class("interlocked")


def test_no_module_tests_a_policys_type_or_picks_one_by_a_name_of_its_own():
    named = re.compile(r"""["'](moving_block|fixed_block)["']""")
    typed = re.compile(r"isinstance\([^)]*(MovingBlockPolicy|FixedBlockPolicy)")
    found = []
    for folder, _dirs, files in os.walk(PACKAGE):
        for name in files:
            if name.endswith(".py"):
                path = os.path.join(folder, name)
                text = open(path).read()
                if typed.search(text) or (named.search(text) and not path.endswith(os.path.join("authority",
                                                                                                 "policy.py"))):
                    found.append(os.path.relpath(path, PACKAGE))
    assert found == [], "name a policy by cbtc.authority.policy's constants; pick one in cbtc.zone.factory"

"""frozen_value: a frozen dataclass made with a faster __init__ behaves as dataclass(frozen=True) makes it."""

import dataclasses
import pickle

import pytest

from cbtc.authority.values import Authority
from cbtc.estimation.estimate import Estimate
from cbtc.frozen import frozen_value


@dataclasses.dataclass(frozen=True)
class Plain:
    a: float
    b: str = "b"
    c: tuple = ()


@frozen_value
class Fast:
    a: float
    b: str = "b"
    c: tuple = ()


def test_a_frozen_value_is_a_frozen_dataclass():
    for args, kwargs in (((1.0,), {}), ((1.0, "x"), {}), ((), {"a": 2.0, "c": (1,)}), ((3,), {"b": "y"})):
        plain, fast = Plain(*args, **kwargs), Fast(*args, **kwargs)
        assert dataclasses.astuple(plain) == dataclasses.astuple(fast)
        assert repr(fast) == repr(plain).replace("Plain", "Fast")
        assert fast == Fast(*args, **kwargs) and hash(fast) == hash(Fast(*args, **kwargs))
        assert fast != Fast(-1.0) and hash(fast) == hash(dataclasses.astuple(fast))
        with pytest.raises(dataclasses.FrozenInstanceError):
            fast.a = 5.0
        assert dataclasses.replace(fast, b="z") == Fast(fast.a, "z", fast.c)
        assert pickle.loads(pickle.dumps(fast)) == fast
    for bad in ((), (1.0, "b", (), 4)):
        with pytest.raises(TypeError):
            Fast(*bad)
    with pytest.raises(TypeError):
        Fast(1.0, d=4)


def test_frozen_value_refuses_what_it_does_not_make():
    with pytest.raises(TypeError, match="plain defaults"):
        @frozen_value
        class WithFactory:
            a: list = dataclasses.field(default_factory=list)
    with pytest.raises(TypeError, match="__post_init__"):
        @frozen_value
        class WithPostInit:
            a: float

            def __post_init__(self):
                pass


def test_the_zones_values_are_frozen_values():
    est = Estimate(1.0, 0.2, 0.01, 0.02, 5.0, 4.9)
    assert (est.ahead_m, est.behind_m, est.age_s) == (0.0, 0.0, pytest.approx(0.1))
    auth = Authority(1.5, 0.5, 0.6, 0.8, "free", "line speed")
    assert auth.cut_to(1.0, "horizon") == dataclasses.replace(auth, distance_m=1.0, reason="horizon")

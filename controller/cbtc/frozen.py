"""Frozen dataclasses of which a zone makes several a report (an estimate, a train's picture, a situation, an
authority): `frozen_value(cls)` is `dataclass(frozen=True)` with an `__init__` that fills the instance's dict in one
step, where dataclass's own sets each field through `object.__setattr__` at about three times the cost. Equality,
hash, repr, `dataclasses.replace` and the refusal to change a field stay dataclass's."""

import dataclasses


def frozen_value(cls):
    """`cls` as a frozen dataclass with the faster `__init__` (same parameters, same defaults)."""
    cls = dataclasses.dataclass(frozen=True)(cls)
    fields = dataclasses.fields(cls)
    if hasattr(cls, "__post_init__"):
        raise TypeError(f"{cls.__name__}: frozen_value makes no __post_init__ call; use dataclass(frozen=True)")
    namespace, params = {}, []
    for field in fields:
        if field.default_factory is not dataclasses.MISSING or not field.init:
            raise TypeError(f"{cls.__name__}.{field.name}: frozen_value takes plain fields with plain defaults")
        if field.default is dataclasses.MISSING:
            params.append(field.name)
        else:
            namespace[f"_default_{field.name}"] = field.default
            params.append(f"{field.name}=_default_{field.name}")
    stores = ", ".join(f"{field.name!r}: {field.name}" for field in fields)
    exec(f"def __init__(self, {', '.join(params)}):\n    self.__dict__.update({{{stores}}})\n", namespace)
    init = namespace["__init__"]
    init.__qualname__ = f"{cls.__qualname__}.__init__"
    init.__doc__ = f"A {cls.__name__} of these field values (frozen_value)."
    cls.__init__ = init
    return cls

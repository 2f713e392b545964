"""Frozen dataclasses made by the thousand, with an `__init__` that fills the instance at once.

`dataclass(frozen=True)` gives a class an `__init__` that sets each field through
`object.__setattr__` (the class's own `__setattr__` refuses): 2.5 us for an 18-field
`Solution`, 1.2 us for a `ModelView`, and replay makes several such results for each of
thousands of samples a second. `fast_init` gives such a class an `__init__` with the same
parameters and defaults that writes the fields into the instance's `__dict__` instead (1.1
and 0.4 us); the class stays a frozen dataclass in every other way (its fields, repr,
equality and pickling, assignment refused). Put it above `@dataclass(frozen=True)`.
"""
from __future__ import annotations

import dataclasses
from typing import Any, TypeVar

T = TypeVar("T")
_FACTORY = object()  # a parameter left out whose default comes from a factory


def fast_init(cls: type[T]) -> type[T]:
    """`cls`, a frozen dataclass without `__post_init__` or fields left out of `__init__`, with the fast
    `__init__` (TypeError for any other class)."""
    params = getattr(cls, "__dataclass_params__", None)
    if params is None or not params.frozen:
        raise TypeError(f"{cls.__name__}: fast_init is for frozen dataclasses")
    fields = dataclasses.fields(cls)  # type: ignore[arg-type]  # a dataclass, as its params say
    if hasattr(cls, "__post_init__") or not all(f.init for f in fields):
        raise TypeError(f"{cls.__name__}: fast_init takes no __post_init__ and no field left out of __init__")
    namespace: dict[str, Any] = {"_FACTORY": _FACTORY}
    parameters, body = [], []
    for f in fields:
        if f.default is not dataclasses.MISSING:
            namespace[f"_default_{f.name}"] = f.default
            parameters.append(f"{f.name}=_default_{f.name}")
        elif f.default_factory is not dataclasses.MISSING:
            namespace[f"_factory_{f.name}"] = f.default_factory
            parameters.append(f"{f.name}=_FACTORY")
            body.append(f"if {f.name} is _FACTORY: {f.name} = _factory_{f.name}()")
        else:
            parameters.append(f.name)
    body.append("values = self.__dict__")
    body += [f"values[{f.name!r}] = {f.name}" for f in fields]
    exec(f"def __init__(self, {', '.join(parameters)}):\n" + "\n".join(f"    {line}" for line in body), namespace)
    init = namespace["__init__"]
    init.__qualname__ = f"{cls.__qualname__}.__init__"
    cls.__init__ = init  # type: ignore[method-assign]
    return cls

"""`fast_init` keeps a frozen dataclass what it was: the same parameters, defaults and factories, the same
instances (equal fields, same repr, pickled alike), assignment refused; only its __init__ is another."""
from __future__ import annotations

import dataclasses
import inspect
import pickle

import numpy as np
import pytest

from cable_winch_monitor.frozen import fast_init
from cable_winch_monitor.model.conditions import Conditions
from cable_winch_monitor.model.estimator.estimation import Estimate
from cable_winch_monitor.model.statics.result import Solution, SolveStatus
from cable_winch_monitor.monitor.alarm import Alarm
from cable_winch_monitor.monitor.basis import Basis
from cable_winch_monitor.monitor.clearance import Clearance
from cable_winch_monitor.monitor.judged import ModelView, MonitorOutput


@dataclasses.dataclass(frozen=True)
class Plain:
    name: str
    count: int = 3
    items: list[int] = dataclasses.field(default_factory=list)


@fast_init
@dataclasses.dataclass(frozen=True)
class Fast:
    name: str
    count: int = 3
    items: list[int] = dataclasses.field(default_factory=list)


def test_a_fast_init_takes_what_the_dataclass_init_takes_and_makes_the_same_instance():
    fast, plain = inspect.signature(Fast.__init__).parameters, inspect.signature(Plain.__init__).parameters
    assert [(p.name, p.kind) for p in fast.values()] == [(p.name, p.kind) for p in plain.values()]
    assert fast["count"].default == 3 and fast["name"].default is inspect.Parameter.empty
    for args, kwargs in (((), {"name": "a"}), (("b", 5), {}), (("c",), {"items": [1, 2]})):
        made, expected = Fast(*args, **kwargs), Plain(*args, **kwargs)
        assert vars(made) == vars(expected) and repr(made).replace("Fast", "Plain") == repr(expected)
        assert vars(pickle.loads(pickle.dumps(made))) == vars(made)
    assert Fast("x").items is not Fast("x").items  # a fresh default from the factory each time
    with pytest.raises(TypeError):
        Fast()  # type: ignore[call-arg]  # the field without a default is still required
    with pytest.raises(dataclasses.FrozenInstanceError):
        Fast("x").count = 4  # type: ignore[misc]


@pytest.mark.parametrize("cls", [Solution, Estimate, Clearance, ModelView, MonitorOutput, Alarm, Basis, Conditions])
def test_the_result_types_stay_frozen_dataclasses(cls):
    fields = dataclasses.fields(cls)
    required = {f.name: f"{f.name}-value" for f in fields
                if f.default is dataclasses.MISSING and f.default_factory is dataclasses.MISSING}
    made = cls(**required)
    assert [f.name for f in fields] == list(vars(made)) and dataclasses.is_dataclass(made)
    assert all(vars(made)[name] == value for name, value in required.items())
    with pytest.raises(dataclasses.FrozenInstanceError):
        setattr(made, fields[0].name, None)


def test_a_solution_keeps_its_defaults_and_what_it_works_out_once():
    lengths = np.array([50.0, 50.1, 50.2, 50.3])
    solution = Solution(SolveStatus.SOLVED, "static equilibrium found", "energy", lengths, taut=np.ones(4, bool))
    assert solution.tension_state == "taut {1,2,3,4}" and solution.extras == {} and solution.load is None
    assert solution.extras is not Solution(SolveStatus.SOLVED, "", "energy", lengths).extras
    assert np.isnan(solution.force_residual) and solution.iterations == 0
    slack = Solution(SolveStatus.SOLVED, "", "energy", lengths, taut=np.array([True, False, True, True]))
    assert slack.taut_set == (1, 3, 4) and slack.tension_state == "taut {1,3,4}"


def test_fast_init_refuses_what_it_cannot_keep():
    @dataclasses.dataclass
    class Open:
        a: int

    @dataclasses.dataclass(frozen=True)
    class Checked:
        a: int

        def __post_init__(self) -> None:
            assert self.a > 0

    for cls in (object, Open, Checked):
        with pytest.raises(TypeError):
            fast_init(cls)

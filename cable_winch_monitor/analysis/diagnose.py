"""Which physical effects does the model lack? Screen every candidate, fit the promising ones, add the best.

Split: interleaved blocks in time (evaluate.split), not the first 70 %: every operating
condition of the bag -- lowering, stops, hoisting, the whole payout range -- then lies
in both parts, so a candidate is judged where it was fitted and not by extrapolation
(a bag that hoists only at its end would otherwise never train sheave friction), while
blocks of at least 10 s keep held-out samples from being near-copies of training ones.
Training rows are thinned to an even spread per sensor (quasi-static data at 10 Hz is
highly redundant): candidates are screened and fitted on a small spread, the chosen ones
refitted jointly on a larger one.

Forward stepwise, a round per effect added (analysis.candidates): every candidate not in
the model is screened cheaply, the promising ones are fitted to convergence, the best few
refitted jointly with the effects added before (a lead with many parameters against pairs
of smaller ones), and of the joint fits the one with the fewest parameters among those
close to the best gain is taken, refitted jointly on the training rows to convergence. A
candidate that gains but is refused (a value at a bound, implausible, not converged, not
identified -- alone or jointly) is reported and passed over, never the end of the ladder.
Rounds go on while the held-out score is above the sensor-noise floor and something is
acceptable. Then every added effect but the last is checked to be still needed: one the
later ones made redundant (a stand-in picked before the effect it stood for) is taken out.

When the final model still misses the data by more than FOUND_SCORE times the sensor
noise, what was added explains the error only in part (an effect the library lacks may
stand behind it): the report says so, and says what the remaining error follows, instead
of calling anything found.

Time budget (analysis.budget): screening takes an equal share of the time left per
candidate, cheapest first (measurement effects reuse the solutions; geometry that refines
the pose costs most); full and joint fits have their shares too. A fit the budget stops
is never added, and every candidate not screened, not fitted fully or not refitted is
listed as unfinished. A progress line shows on a terminal.
"""
from __future__ import annotations

import time
from collections import Counter
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..effects import Effect, PlantModel
from ..effects.model import refines
from ..model.plantfile.plant import Plant, load_plant
from ..progress import Progress
from .bagfields import BagFields, read_fields
from .budget import Budget
from .candidates import PARSIMONY, SETTLE_SHARE, Candidate, Round, finalists, preferred, rivals, screen, settle
from .conditioning import IllConditioned, ill_conditioned
from .data import Dataset, read_bag, require_measurements
from .evaluate import ChannelStats, Evaluator, channel_stats, noise, split, thin
from .fit import FitResult, chi_square, fit_effects
from .follows import Finding, what_follows
from .unsolved import require_solved, unsolved

PER_KIND_QUICK = 25    # training rows per sensor kind to screen candidates on ...
PER_KIND_QUICK_SCORE = 50  # ... and held-out rows to rank them by
PER_KIND_SCREEN = 50   # training rows per sensor kind to fit the promising candidates on
PER_KIND_FIT = 150     # training rows per sensor kind to fit the selected effects on
PER_KIND_SCORE = 150   # held-out rows per sensor kind to judge fits on
NOISE_FLOOR = 1.1      # held-out score at which nothing is left to explain
FOUND_SCORE = 1.3      # a final held-out score above this: the added effects explain the error only in part
MAX_STEPS = 6


@dataclass
class Step:
    """A rung of the ladder: the effect added (None: the given model) or, `removed`, taken out again."""

    added: str | None
    score_train: float
    score_heldout: float
    bic: float
    removed: bool = False

    def label(self) -> str:
        return "model" if self.added is None else f"without {self.added}" if self.removed else self.added


@dataclass
class Refusal:
    """A candidate that gained but was passed over in a round, and why."""

    round: int
    name: str
    reasons: list[str]

    def to_dict(self) -> dict[str, object]:
        return {"round": self.round, "name": self.name, "reasons": self.reasons}


@dataclass
class Diagnosis:
    ranking: list[Candidate]
    ladder: list[Step]
    final: FitResult | None
    model: PlantModel
    train_rows: int
    heldout_rows: int
    solves: int = 0
    channels: dict[str, ChannelStats] = field(default_factory=dict)  # held-out rows under the given model
    follows: list[Finding] = field(default_factory=list)  # what the final model's held-out error follows
    follows_notes: list[str] = field(default_factory=list)
    ill_conditioned: list[IllConditioned] = field(default_factory=list)  # where the lengths do not determine a channel
    unfinished: list[str] = field(default_factory=list)  # what the time budget did not allow
    budget: float | None = None  # [s]
    untried: dict[str, str] = field(default_factory=dict)  # candidate -> why it could not be tried
    unsolved: Counter[str] = field(default_factory=Counter)  # training and held-out rows the model gives no pose
    refused: list[Refusal] = field(default_factory=list)

    @property
    def selected(self) -> list[str]:
        removed = {step.added for step in self.ladder if step.removed}
        return [step.added for step in self.ladder if step.added and not step.removed and step.added not in removed]

    @property
    def partial(self) -> bool:
        """Effects were added, yet the final model misses the held-out data by more than FOUND_SCORE."""
        return bool(self.selected) and self.ladder[-1].score_heldout > FOUND_SCORE

    def found(self, name: str) -> bool:
        """`name` was added, its final values are estimates, and the final model explains the data."""
        return self.final is not None and name in self.selected and self.final.honest(name) and not self.partial


def _cost(cls: type[Effect]) -> int:
    """Screening order: measurement effects reuse solutions, geometry that refines the pose costs most."""
    return {"measurement": 0, "rope_law": 1, "load": 1}.get(cls.acts, 2) + refines(cls)


def _effect(model: PlantModel, name: str) -> Effect:
    """The effect `name` of a model that has it (one added, or a candidate's in its own fit)."""
    effect = model.get(name)
    assert effect is not None, name
    return effect


def _joint(base: PlantModel, effects: list[Effect], rows: Evaluator, noise: np.ndarray, deadline: float | None,
           clock: Budget, what: str) -> FitResult | list[str] | None:
    """The joint fit of `effects` on `rows` from their values; why it cannot be taken where an effect is
    refused; None where the budget stopped it (listed as `what`)."""
    joint = fit_effects(base, effects, rows, noise, deadline)
    if joint.truncated:
        clock.unfinished.append(what)
        return None
    reasons = [r for e in effects for r in joint.refusals(e.name)]
    return [f"fitted jointly with the others: {r}" for r in reasons] if reasons else joint


def _choose(base: PlantModel, added: list[Effect], round_: Round, trials: list[Candidate], train: Evaluator,
            chi2: float, clock: Budget, bar: Progress, refused: list[Refusal]) -> tuple[Candidate | None,
                                                                                          FitResult | None]:
    """The candidate to add and its joint fit with the effects added before on the training rows: each
    finalist (analysis.candidates) is refitted jointly on the fit rows, a lead with many parameters tried
    against pairs of smaller ones, the preferred joint fit refitted on the training rows; a finalist whose
    joint fit is refused, or does not lower the training error, is passed over (listed in `refused`).
    (None, None): nothing, or the budget stopped it."""
    fits, held = round_.rows[1]
    noise, names, score = round_.noise, [e.name for e in added], round_.scores[1]

    def jointly(group: list[Candidate]) -> tuple[FitResult, float] | None:
        """The joint fit of the added effects and `group` on the fit rows, and its held-out score; None where
        it cannot be taken (a refused one is listed)."""
        label = " and ".join(c.name for c in group)
        bar.update(bar.done, f"refitting {', '.join(names)} with {label}" if names else f"refitting {label}")
        joint = _joint(base, [*added, *(_effect(c.fit.model, c.name) for c in group)], fits, noise,
                       clock.part(SETTLE_SHARE), clock, f"candidate {label} (round {round_.number}: its joint fit "
                       "stopped at the budget)")
        if isinstance(joint, list) and len(group) == 1:
            group[0].refused = joint
            refused.append(Refusal(round_.number, group[0].name, joint))
        return (joint, held.score(joint.model, noise)) if isinstance(joint, FitResult) else None

    order = preferred([(c, *fit) for c in finalists(trials) if (fit := jointly([c])) is not None], score)
    for a, b in rivals(order[0][0], trials) if order else ():
        pair = jointly([a, b])
        if pair is not None and score ** 2 - pair[1] ** 2 >= PARSIMONY * (score ** 2 - order[0][2] ** 2):
            first = next((j for j in order if j[0] is a), None) or ((a, *fit) if (fit := jointly([a])) else None)
            order = ([first] if first else []) + [j for j in order if j[0] is not a]
            break
    for chosen, joint, _ in order:
        bar.update(bar.done, f"refitting {', '.join(names + [chosen.name])} on the training rows")
        final = _joint(base, [_effect(joint.model, n) for n in names + [chosen.name]], train, noise, clock.part(1.0),
                       clock, f"candidate {chosen.name} (its joint fit with {', '.join(names) or 'nothing'} on the "
                       "training rows stopped at the budget)")
        if final is None:
            return None, None
        reasons = final if isinstance(final, list) else \
            ["the joint fit does not lower the training error"] if final.chi2 > chi2 else []
        if not reasons:
            assert isinstance(final, FitResult)  # `_joint` refuses with at least one reason
            return chosen, final
        chosen.refused = reasons
        refused.append(Refusal(round_.number, chosen.name, reasons))
    return None, None


def _prune(base: PlantModel, final: FitResult, rows: tuple[Evaluator, Evaluator], train: Evaluator,
           noise: np.ndarray, clock: Budget, bar: Progress, ladder: list[Step]) -> FitResult | None:
    """Take out every added effect that no longer gains once the later ones are in (a stand-in picked before
    the effect it stood for): refitted jointly without it on the fit `rows`, the others explain as much
    -- it would not be added again (analysis.candidates: Delta BIC and held-out score). The joint fit of
    those left on the training rows, the removals appended to the `ladder`; None where nothing was taken
    out or the budget did not allow it (listed)."""
    fits, held = rows
    model = final.model
    kept = [e for e in model.effects if base.get(e.name) is None]
    removed: list[str] = []
    for name in [e.name for e in kept][:-1]:  # the last one added was just shown to gain with the others
        if clock.spent():
            clock.unfinished.append(f"the check that {name} is still needed")
            continue
        bar.update(bar.done, f"checking that {name} is still needed")
        without = fit_effects(base, [e for e in kept if e.name != name], fits, noise, clock.part(SETTLE_SHARE))
        if without.truncated:
            clock.unfinished.append(f"the check that {name} is still needed")
            continue
        (chi2, _), (held_chi2, count) = chi_square(model, fits, noise), chi_square(model, held, noise)
        penalty = len(_effect(model, name).fitted()) * np.log(max(count, 1))
        needed = Candidate(name, final, held.score(without.model, noise), held.score(model, noise),
                           chi2 + penalty - without.chi2, held_chi2 + penalty - chi_square(without.model, held, noise)[0],
                           screened=False)
        if not needed.gains:
            model, removed = without.model, removed + [name]
            kept = [e for e in model.effects if base.get(e.name) is None]
    if not removed:
        return None
    joint = fit_effects(base, kept, train, noise, clock.part(1.0))
    if not joint.converged:
        clock.unfinished.append(f"the joint fit without {', '.join(removed)}")
        return None
    ladder += [Step(name, float(np.sqrt(joint.chi2 / max(joint.count, 1))), held.score(joint.model, noise), joint.bic,
                    removed=True) for name in removed]
    return joint


def diagnose(base: PlantModel, data: Dataset, noise: np.ndarray, candidates: list[str] | None = None,
             fields: BagFields | None = None, budget: float | None = None, progress: bool = False) -> Diagnosis:
    """Rank the candidate effects (default: every known effect not in `base`) and select forward-stepwise;
    then rank what the final model's held-out error follows (among the bag's other `fields` too). Within
    `budget` seconds (None: no limit; what did not fit in it is listed in `unfinished`), with a progress
    line on a terminal if `progress`."""
    clock = Budget(budget)
    train_rows, held_out = split(data)
    held_rows = thin(held_out, data.kinds, PER_KIND_SCORE)
    train = Evaluator(data.subset(thin(train_rows, data.kinds, PER_KIND_FIT)), base)
    held = Evaluator(data.subset(held_rows), base)
    rows = ((Evaluator(data.subset(thin(train_rows, data.kinds, PER_KIND_QUICK)), base),
             Evaluator(data.subset(thin(held_out, data.kinds, PER_KIND_QUICK_SCORE)), base)),
            (Evaluator(data.subset(thin(train_rows, data.kinds, PER_KIND_SCREEN)), base), held))
    known = base.registry.available()
    pool = sorted((n for n in (candidates or known) if base.get(n) is None and known[n].fittable()),
                  key=lambda n: _cost(known[n]))
    untried = {n: "the bag lacks " + ", ".join(i.key for i in known[n].inputs if i.key not in data.inputs)
               for n in pool if any(i.key not in data.inputs for i in known[n].inputs)}
    pool = [n for n in pool if n not in untried]
    bar = Progress("diagnose", len(pool), enabled=progress, only_tty=True)
    current = base
    added: list[Effect] = []
    final: FitResult | None = None
    require_solved(data.bag, held.solutions(base), "score a candidate on", "held-out row")
    not_solved = unsolved(train.solutions(base) + held.solutions(base))
    chi2, count = chi_square(current, train, noise)
    ladder = [Step(None, float(np.sqrt(chi2 / max(count, 1))), held.score(current, noise), chi2)]
    ranking: list[Candidate] = []
    trials: list[Candidate] = []
    refused: list[Refusal] = []
    for number in range(1, MAX_STEPS + 1):
        if (added and ladder[-1].score_heldout <= NOISE_FLOOR) or not pool:
            break
        if clock.spent():
            clock.unfinished += [f"candidate {n} (round {number}: not screened)" for n in pool]
            break
        round_ = Round(current, rows, noise, number)
        trials = settle(round_, screen(round_, pool, trials, clock, bar), clock, bar)
        ranking = ranking or trials
        refused += [Refusal(number, c.name, c.refused) for c in trials if not c.screened and c.gains and c.refused]
        chosen, joint = _choose(base, added, round_, trials, train, chi2, clock, bar, refused)
        if chosen is None or joint is None:  # both or neither
            break
        final, chi2 = joint, joint.chi2
        current = final.model
        added = [_effect(current, e.name) for e in [*added, _effect(chosen.fit.model, chosen.name)]]
        pool.remove(chosen.name)
        assert bar.total is not None  # the bar counts the pool
        bar.total += len(pool)
        ladder.append(Step(chosen.name, float(np.sqrt(final.chi2 / max(final.count, 1))), held.score(current, noise),
                           final.bic))
    if len(added) > 1:
        assert final is not None  # the joint fit of the effects added
        final = _prune(base, final, rows[1], train, noise, clock, bar, ladder) or final
        current = final.model
    for candidate in ranking:
        candidate.selected = candidate.name in {e.name for e in current.effects} - {e.name for e in base.effects}
    channels = channel_stats(held.residuals(base), held.data.measured, noise, held.data.channels)
    conditioning: list[IllConditioned] = []
    if clock.spent():
        clock.unfinished.append("the identifiability check (ill-conditioned channels)")
    else:
        bar.update(bar.done, "checking identifiability")
        conditioning = ill_conditioned(current, data, noise)
    bar.finish()
    follows = what_follows(data, held.residuals(current), noise, held_rows, fields, current.channels)
    return Diagnosis(ranking, ladder, final, current, len(train.data), len(held.data),
                     sum(e.solves for part in rows for e in part) + train.solves, channels, follows,
                     fields.remarks() if fields else [], conditioning, clock.unfinished, budget, untried, not_solved, refused)


def diagnose_bag(bag: str | Path, plant: Plant | None = None, candidates: list[str] | None = None,
                 budget: float | None = None, progress: bool = False) -> tuple[Diagnosis, Dataset]:
    """Read a bag and diagnose it against a plant (the bundled one by default), its effects included;
    the diagnosis and the bag's measurements."""
    started = time.monotonic()
    model, data = diagnosis_inputs(bag, plant, candidates)
    require_measurements(data)
    fields = read_fields(bag)
    left = None if budget is None else budget - (time.monotonic() - started)  # reading counts too
    return diagnose(model, data, noise(model, data)[0], candidates, fields, left, progress), data


def diagnosis_inputs(bag: str | Path, plant: Plant | None = None,
                     candidates: list[str] | None = None) -> tuple[PlantModel, Dataset]:
    """The plant model (the bundled plant by default) and the bag's measurements, with the extra inputs
    the model's effects read and those of the candidates where the bag has them."""
    model = PlantModel.from_plant(plant or load_plant())
    own = {i.key for i in model.inputs}
    known = model.registry.available()
    wanted = {i.key: i for name in (candidates or known) for i in known[name].inputs if i.key not in own}
    return model, read_bag(bag, model, tuple(wanted.values()))

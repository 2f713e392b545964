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
the model is screened cheaply, the promising ones are fitted to convergence, and the
acceptable one with the fewest parameters among those close to the best gain is picked;
a candidate that gains but is refused (a value at a bound, implausible, not converged,
not identified) is reported and passed over, never the end of the ladder. The picked
effect is refitted jointly with those added before, from the last optimum, to
convergence; if the joint fit refuses it (a value at a bound, or no lower training error)
the next acceptable candidate is tried. Rounds go on while the held-out score is above the
sensor-noise floor and something is acceptable.

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
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..effects import Effect, PlantModel, available
from ..effects.model import refines
from ..model.plant import Plant, load_plant
from ..progress import Progress
from .bagfields import BagFields, read_fields
from .budget import Budget
from .candidates import Candidate, Round, finalists, screen, settle
from .conditioning import IllConditioned, ill_conditioned
from .data import Dataset, read_bag, require_measurements
from .evaluate import ChannelStats, Evaluator, channel_stats, noise, split, thin
from .fit import FitResult, chi_square, fit_effects
from .follows import Finding, what_follows

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
    added: str | None
    score_train: float
    score_heldout: float
    bic: float


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
    refused: list[Refusal] = field(default_factory=list)

    @property
    def selected(self) -> list[str]:
        return [step.added for step in self.ladder if step.added]

    @property
    def partial(self) -> bool:
        """Effects were added, yet the final model misses the held-out data by more than FOUND_SCORE."""
        return bool(self.selected) and self.ladder[-1].score_heldout > FOUND_SCORE

    def found(self, name: str) -> bool:
        """`name` was added, its final values are estimates, and the final model explains the data."""
        return self.final is not None and name in self.selected and self.final.honest(name) and not self.partial


def _cost(name: str) -> int:
    """Screening order: measurement effects reuse solutions, geometry that refines the pose costs most."""
    cls = available()[name]
    return {"measurement": 0, "rope_law": 1, "load": 1}.get(cls.acts, 2) + refines(cls)


def _refit(base: PlantModel, added: list[Effect], chosen: Candidate, train: Evaluator, noise: np.ndarray,
           chi2: float, clock: Budget) -> FitResult | list[str] | None:
    """The joint fit of the added effects and the chosen one from the last optimum; why it cannot be taken
    where it is refused or does not lower the training error; None where the budget stopped it (listed)."""
    joint = fit_effects(base, [*added, chosen.fit.model.get(chosen.name)], train, noise, clock.part(1.0))
    if joint.truncated:
        names = ", ".join(e.name for e in added)
        clock.unfinished.append(f"candidate {chosen.name} (its joint fit{' with ' + names if names else ''} stopped "
                                "at the budget)")
        return None
    reasons = [r for e in [*added, chosen.fit.model.get(chosen.name)] for r in joint.refusals(e.name)]
    if joint.chi2 > chi2:
        reasons.append("the joint fit does not lower the training error")
    return [f"fitted jointly with the others: {r}" for r in reasons] if reasons else joint


def _choose(base: PlantModel, added: list[Effect], trials: list[Candidate], train: Evaluator, held: Evaluator,
            noise: np.ndarray, chi2: float, clock: Budget, bar: Progress, refused: list[Refusal],
            number: int) -> tuple[Candidate | None, FitResult | None]:
    """The candidate to add and its joint fit with the effects added before: of the finalists
    (analysis.candidates), the one whose joint fit scores best on the held-out rows; a finalist the joint
    fit refuses is passed over (and listed in `refused`), the next ones tried. (None, None): nothing."""
    while picked := finalists(trials):
        fitted = []
        for chosen in picked:
            bar.update(bar.done, f"refitting {', '.join([e.name for e in added] + [chosen.name])}")
            joint = _refit(base, added, chosen, train, noise, chi2, clock)
            if joint is None:
                return None, None  # the budget is spent
            if isinstance(joint, list):
                chosen.refused = joint
                refused.append(Refusal(number, chosen.name, joint))
            else:
                fitted.append((held.score(joint.model, noise), chosen, joint))
        if fitted:
            _, chosen, joint = min(fitted, key=lambda f: f[0])
            return chosen, joint
    return None, None


def diagnose(base: PlantModel, data: Dataset, noise: np.ndarray, candidates: list[str] | None = None,
             fields: BagFields | None = None, budget: float | None = None, progress: bool = False) -> Diagnosis:
    """Rank the candidate effects (default: every known effect not in `base`) and select forward-stepwise;
    then rank what the final model's held-out error follows (among the bag's other `fields` too). Within
    `budget` seconds (None: no limit; what did not fit in it is listed in `unfinished`), with a progress
    line on a terminal if `progress`."""
    clock = Budget(budget)
    train_rows, held_rows = split(data)
    train = Evaluator(data.subset(thin(train_rows, data.kinds, PER_KIND_FIT)), base)
    held = Evaluator(data.subset(thin(held_rows, data.kinds, PER_KIND_SCORE)), base)
    rows = ((Evaluator(data.subset(thin(train_rows, data.kinds, PER_KIND_QUICK)), base),
             Evaluator(data.subset(thin(held_rows, data.kinds, PER_KIND_QUICK_SCORE)), base)),
            (Evaluator(data.subset(thin(train_rows, data.kinds, PER_KIND_SCREEN)), base), held))
    held_rows = thin(held_rows, data.kinds, PER_KIND_SCORE)
    pool = sorted((n for n in (candidates or available()) if base.get(n) is None and available()[n].fittable()),
                  key=_cost)
    untried = {n: "the bag lacks " + ", ".join(i.key for i in available()[n].inputs if i.key not in data.inputs)
               for n in pool if any(i.key not in data.inputs for i in available()[n].inputs)}
    pool = [n for n in pool if n not in untried]
    bar = Progress("diagnose", len(pool), enabled=progress, only_tty=True)
    current, added, final = base, [], None
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
        chosen, joint = _choose(base, added, trials, train, held, noise, chi2, clock, bar, refused, number)
        if joint is None:
            break
        final, chi2 = joint, joint.chi2
        current = final.model
        added = [current.get(e.name) for e in [*added, chosen.fit.model.get(chosen.name)]]
        pool.remove(chosen.name)
        bar.total += len(pool)
        ladder.append(Step(chosen.name, float(np.sqrt(final.chi2 / max(final.count, 1))), held.score(current, noise),
                           final.bic))
    for candidate in ranking:
        candidate.selected = candidate.name in [step.added for step in ladder]
    channels = channel_stats(held.residuals(base), held.data.measured, noise, held.data.channels)
    conditioning: list[IllConditioned] = []
    if clock.spent():
        clock.unfinished.append("the identifiability check (ill-conditioned channels)")
    else:
        bar.update(bar.done, "checking identifiability")
        conditioning = ill_conditioned(current, data, noise)
    bar.finish()
    follows = what_follows(data, held.residuals(current), noise, held_rows, fields)
    return Diagnosis(ranking, ladder, final, current, len(train.data), len(held.data),
                     sum(e.solves for part in rows for e in part) + train.solves, channels, follows,
                     fields.remarks() if fields else [], conditioning, clock.unfinished, budget, untried, refused)


def diagnose_bag(bag: str | Path, plant: Plant | None = None, candidates: list[str] | None = None,
                 budget: float | None = None, progress: bool = False) -> tuple[Diagnosis, Dataset]:
    """Read a bag and diagnose it against a plant (the bundled one by default), its effects included;
    the diagnosis and the bag's measurements."""
    started = time.monotonic()
    model, data = diagnosis_inputs(bag, plant, candidates)
    require_measurements(data)
    fields = read_fields(bag)
    left = None if budget is None else budget - (time.monotonic() - started)  # reading counts too
    return diagnose(model, data, noise(model.plant, data)[0], candidates, fields, left, progress), data


def diagnosis_inputs(bag: str | Path, plant: Plant | None = None,
                     candidates: list[str] | None = None) -> tuple[PlantModel, Dataset]:
    """The plant model (the bundled plant by default) and the bag's measurements, with the extra inputs
    the model's effects read and those of the candidates where the bag has them."""
    model = PlantModel.from_plant(plant or load_plant())
    own = {i.key for i in model.inputs}
    wanted = {i.key: i for name in (candidates or available()) for i in available()[name].inputs if i.key not in own}
    return model, read_bag(bag, model.inputs, tuple(wanted.values()))

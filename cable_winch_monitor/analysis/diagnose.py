"""Which physical effect does the model lack? Fit each candidate on training data, score it on held-out data.

Split: interleaved blocks in time (evaluate.split), not the first 70 %: every operating
condition of the bag -- lowering, stops, hoisting, the whole payout range -- then lies
in both parts, so a candidate is judged where it was fitted and not by extrapolation
(a bag that hoists only at its end would otherwise never train sheave friction), while
blocks of at least 10 s keep held-out samples from being near-copies of training ones.
Training rows are thinned to an even spread per sensor (quasi-static data at 10 Hz is
highly redundant): candidates are screened on a small spread, the chosen ones refitted
on a larger one. With per-row warm starts and reused solutions for measurement effects
this keeps a 20-minute bag within minutes.

Forward stepwise: screen every candidate not in the model (others held at their
values), rank by held-out score and Delta BIC, add the best while its held-out score falls and its Delta BIC is below
MAX_DELTA_BIC both on the training rows and on the held-out rows (chi-square change plus
k ln n there: the error must fall on data the fit never saw, by more than chance), its held-out
score falls by at least MIN_GAIN and its fit is honest (no parameter stopped by a bound, no
physically implausible value: analysis.fit), then refit the added effects jointly from the
previous step's optimum (the effect is not added if the refit ends with a higher training error
than the step before). Every candidate is screened at least once (the ranking is the report);
further rounds only while the held-out score is above the sensor-noise floor.

Time budget: candidates are screened cheapest first (measurement effects reuse the
solutions; geometry that refines the pose costs most), each with an equal share of the
time left for the round, a fit stopping at its share with the best values met (never
"found": analysis.fit); once the budget is spent the remaining candidates and checks are
skipped and listed. A progress line shows on a terminal.
"""
from __future__ import annotations

import time
from collections import Counter
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from ..effects import PlantModel, available
from ..effects.model import refines
from ..model.plant import Plant, load_plant
from ..progress import Progress
from .conditioning import IllConditioned, ill_conditioned
from .bagfields import BagFields, read_fields
from .data import Dataset, read_bag, require_measurements
from .evaluate import ChannelStats, Evaluator, channel_stats, noise, split, thin
from .fit import FitResult, chi_square, fit_effects
from .follows import Finding, what_follows
from .unsolved import require_solved, unsolved

PER_KIND_SCREEN = 50   # training rows per sensor kind to screen candidates on
PER_KIND_FIT = 150     # training rows per sensor kind to fit the selected effects on
PER_KIND_SCORE = 150   # held-out rows per sensor kind
MAX_DELTA_BIC = -10.0  # "very strong" evidence (Kass and Raftery)
MIN_GAIN = 0.02        # relative fall of the held-out score an effect must bring to be selected
SCREEN_SHARE = 0.6     # share of the time left a screening round may take (split among its candidates)
REFIT_SHARE = 0.5      # share of the time left the joint refit of the selected effects may take
RESERVE = 0.2          # share of the budget kept for scoring the last fits on the held-out rows and the report

NOISE_FLOOR = 1.1      # held-out score at which nothing is left to explain
MAX_STEPS = 4


@dataclass
class Candidate:
    """One screened effect: its fit on the training rows and its held-out score."""

    name: str
    fit: FitResult
    score_before: float
    score_after: float
    delta_bic: float
    heldout_delta_bic: float = 0.0
    selected: bool = False

    def to_dict(self) -> dict[str, Any]:
        return {"name": self.name, "title": type(self.fit.model.get(self.name)).title,
                "params": {k: v["value"] for k, v in self.fit.params(self.name).items()},
                "uncertainties": {k: v["sigma"] for k, v in self.fit.params(self.name).items()},
                "units": {k: v["unit"] for k, v in self.fit.params(self.name).items()},
                "score_before": self.score_before, "score_after": self.score_after, "delta_bic": self.delta_bic, "heldout_delta_bic": self.heldout_delta_bic,
                "selected": self.selected, "honest": self.fit.honest(self.name), "at_bound": self.fit.at_bound,
                "implausible": self.fit.implausible, "correlations": self.fit.correlations(),
                "warnings": self.fit.warnings}


@dataclass
class Step:
    added: str | None
    score_train: float
    score_heldout: float
    bic: float


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
    skipped: list[str] = field(default_factory=list)  # what the time budget left out
    budget: float | None = None  # [s]
    untried: dict[str, str] = field(default_factory=dict)  # candidate -> why it could not be tried
    unsolved: Counter[str] = field(default_factory=Counter)  # training and held-out rows the model gives no pose

    @property
    def selected(self) -> list[str]:
        return [step.added for step in self.ladder if step.added]


class Budget:
    """Wall time a diagnosis may take (None: unbounded): deadlines for its parts, what was skipped."""

    def __init__(self, seconds: float | None):
        self.seconds = seconds
        self.deadline = None if seconds is None else time.monotonic() + seconds
        self.skipped: list[str] = []

    def left(self) -> float:
        return np.inf if self.deadline is None else self.deadline - time.monotonic()

    def spent(self) -> bool:
        """Nothing new starts now: what is left is the reserve for the held-out scores and the report."""
        return self.left() <= RESERVE * (self.seconds or 0.0)

    def part(self, share: float) -> float | None:
        """A deadline for a part that may take `share` of the time left before the reserve."""
        if self.deadline is None:
            return None
        return time.monotonic() + share * max(self.left() - RESERVE * self.seconds, 0.0)


def _cost(name: str) -> int:
    """Screening order: measurement effects reuse solutions, geometry that refines the pose costs most."""
    cls = available()[name]
    return {"measurement": 0, "rope_law": 1, "load": 1}.get(cls.acts, 2) + refines(cls)


def _screen(current: PlantModel, names: list[str], train: Evaluator, held: Evaluator, noise: np.ndarray,
            score_now: float, bic_now: float, budget: Budget, bar: Progress) -> list[Candidate]:
    """Fit each candidate on the training rows, score it on the held-out rows; each gets an equal share
    of SCREEN_SHARE of the time left, those met after the budget is spent are skipped."""
    known = available()
    chi2_before, count = chi_square(current, held, noise)
    trials = []
    for k, name in enumerate(names):
        bar.update(bar.done, f"screening {name}")
        if budget.spent():
            budget.skipped.append(f"candidate {name}")
            continue
        deadline = budget.part(SCREEN_SHARE / (len(names) - k))
        fit = fit_effects(current, [known[name](plant=current.plant)], train, noise, deadline)
        after = held.score(fit.model, noise)
        held_bic = chi_square(fit.model, held, noise)[0] - chi2_before + len(fit.free) * np.log(max(count, 1))
        trials.append(Candidate(name, fit, score_now, after, fit.bic - bic_now, float(held_bic)))
        bar.update(bar.done + 1)
    return sorted(trials, key=lambda c: (c.score_after, c.delta_bic))


def _significant(candidate: Candidate) -> bool:
    """A real, honest gain: strong BIC evidence on both parts, a held-out score falling by MIN_GAIN, values
    that are estimates (not stopped by a bound, physically plausible)."""
    return (candidate.delta_bic < MAX_DELTA_BIC and candidate.heldout_delta_bic < MAX_DELTA_BIC
            and candidate.score_after <= (1.0 - MIN_GAIN) * candidate.score_before
            and candidate.fit.honest(candidate.name))


def diagnose(base: PlantModel, data: Dataset, noise: np.ndarray, candidates: list[str] | None = None,
             fields: BagFields | None = None, budget: float | None = None, progress: bool = False) -> Diagnosis:
    """Rank the candidate effects (default: every known effect not in `base`) and select forward-stepwise;
    then rank what the final model's held-out error follows (among the bag's other `fields` too). Within
    `budget` seconds (None: no limit; what did not fit in it is listed in `skipped`), with a progress
    line on a terminal if `progress`."""
    clock = Budget(budget)
    train_rows, held_rows = split(data)
    screen = Evaluator(data.subset(thin(train_rows, data.kinds, PER_KIND_SCREEN)))
    train = Evaluator(data.subset(thin(train_rows, data.kinds, PER_KIND_FIT)))
    held_rows = thin(held_rows, data.kinds, PER_KIND_SCORE)
    held = Evaluator(data.subset(held_rows))
    pool = sorted((n for n in (candidates or available()) if base.get(n) is None and available()[n].fittable()),
                  key=_cost)
    untried = {n: "the bag lacks " + ", ".join(i.key for i in available()[n].inputs if i.key not in data.inputs)
               for n in pool if any(i.key not in data.inputs for i in available()[n].inputs)}
    pool = [n for n in pool if n not in untried]
    bar = Progress("diagnose", len(pool), enabled=progress, only_tty=True)
    current, added, final = base, [], None
    require_solved(data.bag, held.solutions(base), "score a candidate on", "held-out row")
    not_solved = unsolved(train.solutions(base) + held.solutions(base))
    chi2, count = chi_square(current, train, noise)
    score_now = held.score(current, noise)
    ladder = [Step(None, float(np.sqrt(chi2 / max(count, 1))), score_now, chi2)]
    bic_screen = chi_square(current, screen, noise)[0]
    ranking: list[Candidate] = []
    for _ in range(MAX_STEPS):
        if (added and score_now <= NOISE_FLOOR) or not pool:
            break
        if clock.spent():
            clock.skipped += [f"candidate {n}" for n in pool] if not ranking else ["a further selection round"]
            break
        trials = _screen(current, pool, screen, held, noise, score_now, bic_screen, clock, bar)
        ranking = ranking or trials
        if not trials or not _significant(trials[0]) or trials[0].score_after >= score_now:
            break
        best = trials[0]
        bar.update(bar.done, f"refitting {', '.join([e.name for e in added] + [best.name])}")
        joint = fit_effects(base, [*added, best.fit.model.get(best.name)], train, noise,  # from the last optimum
                            clock.part(REFIT_SHARE))
        if joint.chi2 > chi2:  # the refit could not keep the training error: the effect does not help
            break
        final, chi2 = joint, joint.chi2
        added.append(best.fit.model.get(best.name))
        current = final.model
        bic_screen = chi_square(current, screen, noise)[0] + final.bic - final.chi2
        added = [current.get(e.name) for e in added]
        pool.remove(best.name)
        bar.total += len(pool)
        score_now = held.score(current, noise)
        ladder.append(Step(best.name, float(np.sqrt(final.chi2 / max(final.count, 1))), score_now, final.bic))
    for candidate in ranking:
        candidate.selected = candidate.name in [step.added for step in ladder]
    channels = channel_stats(held.residuals(base), held.data.measured, noise, held.data.channels)
    conditioning: list[IllConditioned] = []
    if clock.spent():
        clock.skipped.append("the identifiability check (ill-conditioned channels)")
    else:
        bar.update(bar.done, "checking identifiability")
        conditioning = ill_conditioned(current, data, noise)
    bar.finish()
    follows = what_follows(data, held.residuals(current), noise, held_rows, fields)
    return Diagnosis(ranking, ladder, final, current, len(train.data), len(held.data),
                     screen.solves + train.solves + held.solves, channels, follows,
                     fields.remarks() if fields else [], conditioning, clock.skipped, budget, untried, not_solved)


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

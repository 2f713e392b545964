"""One round of the diagnosis: screen every candidate effect cheaply, fit the promising ones fully, pick one.

Screening fits each candidate alone (the model's other effects held) on a small spread of
training rows with two Gauss-Newton steps from its defaults (QUICK_EVALUATIONS), or one
from its values in the round before (they move little when one effect is added; where the
effect added took over their part, from the defaults again): enough to rank them, not to
report their values as estimates. The promising ones -- their training chi-square
already falls by the BIC margin -- are then fitted to convergence on a larger spread, best
screened first, until SHORTLIST of them are acceptable or none is left, and then those
screened within SCREEN_MARGIN of the last of them: a screening ranks candidates only to its
precision, and one with many parameters (eight load-pin zeros and gains) is farther from its
optimum after two steps than one with a few.

Acceptable: a real gain (Delta BIC below MAX_DELTA_BIC on the training and on the
held-out rows, the held-out score falling by MIN_GAIN) and a fit that is a finding (no
value at a bound, none implausible, converged, identified: `FitResult.refusals`). A
candidate that gains but is refused is reported and passed over; the next one is taken.
The acceptable candidates best by held-out score, and the one with the fewest parameters
among those close to the best gain, are the finalists: each is refitted jointly with the
effects added before (diagnose), since one fitted alone is judged with the others holding
what they took over from it (an encoder's zero, after its scale took part of it, gains
less than an inclinometer offset that only looks like it). Of the joint fits, the one with
the fewest parameters whose held-out gain (in chi-square) is at least PARSIMONY of the
best's is taken: four encoder scales mimic the elastic stretch of four ropes (T_i l / EA
per rope) almost as well as EA does, and an over-flexible stand-in taken first blocks the
physical effect behind it; a centre of gravity a few millimetres off tilts the platform
almost as an AHRS mounted tilted reads. A lead with many parameters is tried against pairs
of smaller acceptable candidates with no more parameters together (`rivals`): eight load-pin
zeros and gains take over the tension share of a winch's zero and of the centre of gravity
in one step, where each of the two physical effects explains only part; if the pair explains
as much, its better member is added (the other follows in the next round).
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from ..effects import PlantModel
from ..progress import Progress
from .budget import Budget
from .evaluate import Evaluator
from .fit import MAX_EVALUATIONS, FitResult, chi_square, fit_effects

MAX_DELTA_BIC = -10.0  # "very strong" evidence (Kass and Raftery)
MIN_GAIN = 0.02        # relative fall of the held-out score an effect must bring to be selected
QUICK_EVALUATIONS = 3  # a screening fit: the start and two Gauss-Newton steps (one from the last round's values)
SHORTLIST = 3          # acceptable candidates fitted fully per round before one is picked
SCREEN_MARGIN = 0.1    # candidates screened within this share of the shortlist's last are fitted fully too
PARSIMONY = 0.9        # a simpler candidate with this share of the best held-out gain is picked instead
FINALISTS = 2          # the best acceptable candidates refitted jointly (on the screening's fit rows) before one is picked
PAIRS = 2              # pairs of smaller candidates refitted jointly against a lead with as many parameters as both
SCREEN_SHARE = 0.5     # share of the time left a screening round may take (split among its candidates)
SETTLE_SHARE = 0.3     # share of the time left one full fit may take


@dataclass
class Candidate:
    """One effect tried on the current model: its fit on the training rows and its held-out score;
    `screened` while its fit is the screening's few steps, `refused` why its gain is no finding."""

    name: str
    fit: FitResult
    score_before: float
    score_after: float
    delta_bic: float
    heldout_delta_bic: float = 0.0
    selected: bool = False
    screened: bool = True
    refused: list[str] = field(default_factory=list)

    @property
    def gains(self) -> bool:
        """A real gain: strong BIC evidence on both parts and a held-out score falling by MIN_GAIN."""
        return (self.delta_bic < MAX_DELTA_BIC and self.heldout_delta_bic < MAX_DELTA_BIC
                and self.score_after <= (1.0 - MIN_GAIN) * self.score_before)

    @property
    def acceptable(self) -> bool:
        return not self.screened and self.gains and not self.refused

    @property
    def gain(self) -> float:
        """The fall of the held-out chi-square per value (the score squared)."""
        return self.score_before ** 2 - self.score_after ** 2

    def to_dict(self) -> dict[str, Any]:
        params = self.fit.params(self.name)
        effect = self.fit.model.get(self.name)
        assert effect is not None  # the candidate's fit holds it
        return {"name": self.name, "title": type(effect).title,
                "params": {k: v["value"] for k, v in params.items()},
                "uncertainties": {k: v["sigma"] for k, v in params.items()},
                "units": {k: v["unit"] for k, v in params.items()},
                "score_before": self.score_before, "score_after": self.score_after, "delta_bic": self.delta_bic,
                "heldout_delta_bic": self.heldout_delta_bic, "selected": self.selected, "screened_only": self.screened,
                "refused": self.refused, "converged": self.fit.converged, "honest": self.fit.honest(self.name),
                "at_bound": self.fit.at_bound, "implausible": self.fit.implausible,
                "correlations": self.fit.correlations(), "warnings": self.fit.warnings}


class Round:
    """The current model; the training and held-out rows to screen on (a small spread) and to fit and score
    the promising candidates on (a larger one), and where the model stands on them."""

    def __init__(self, current: PlantModel, rows: tuple[tuple[Evaluator, Evaluator], tuple[Evaluator, Evaluator]],
                 noise: np.ndarray, number: int):
        self.current, self.rows, self.noise, self.number = current, rows, noise, number
        self.scores = [held.score(current, noise) for _, held in rows]  # the screening's, the fits'
        # the model's own parameters count in every trial alike
        self.chi2 = [[chi_square(current, evaluator, noise) for evaluator in part] for part in rows]

    def trial(self, name: str, start: Any, deadline: float | None, quick: bool) -> Candidate:
        """Fit `name` from the effect `start` (None: its defaults) alone on the current model, `quick`ly (the
        screening's steps on the screening rows: one fewer from a start found before) or to convergence;
        score it on the held-out rows."""
        effect = start if start is not None else self.current.registry.effect_class(name)(plant=self.current.plant)
        part = 0 if quick else 1
        (train, held), ((train_chi2, _), (held_chi2, held_count)) = self.rows[part], self.chi2[part]
        fit = fit_effects(self.current, [effect], train, self.noise, deadline,
                          QUICK_EVALUATIONS - (start is not None) if quick else MAX_EVALUATIONS)
        held_bic = chi_square(fit.model, held, self.noise)[0] - held_chi2 + len(fit.free) * np.log(max(held_count, 1))
        return Candidate(name, fit, self.scores[part], held.score(fit.model, self.noise), fit.bic - train_chi2,
                         float(held_bic), screened=quick, refused=[] if quick else fit.refusals(name))


def screen(round_: Round, names: list[str], before: list[Candidate], budget: Budget, bar: Progress) -> list[Candidate]:
    """Every candidate's screening fit, from its values in the round `before` where they were no bound's,
    best held-out score first; those the budget leaves out are listed in it as unfinished."""
    starts = {c.name: c.fit.model.get(c.name) for c in before if not any(
        label.startswith(f"{c.name}.") for label in c.fit.at_bound)}
    trials = []
    for k, name in enumerate(names):
        bar.update(bar.done, f"screening {name}")
        if budget.spent():
            budget.unfinished += [f"candidate {n} (round {round_.number}: not screened)" for n in names[k:]]
            break
        deadline = budget.part(SCREEN_SHARE / (len(names) - k))
        trial = round_.trial(name, starts.get(name), deadline, quick=True)
        if name in starts and trial.delta_bic > 0.0:  # the last round's values fit this model worse than none
            trial = round_.trial(name, None, deadline, quick=True)
        trials.append(trial)
        bar.update(bar.done + 1)
    return sorted(trials, key=lambda c: (c.score_after, c.delta_bic))


def settle(round_: Round, trials: list[Candidate], budget: Budget, bar: Progress) -> list[Candidate]:
    """Fit the promising screened candidates to convergence, best first, until SHORTLIST are acceptable and
    those screened within SCREEN_MARGIN of the last of them; the ranking with each fitted candidate in place
    of its screening."""
    out, acceptable, cutoff = list(trials), 0, math.inf  # cutoff: the screened score beyond which none is fitted
    for k, candidate in enumerate(trials):
        if candidate.score_after > cutoff or candidate.delta_bic >= MAX_DELTA_BIC:
            continue
        if budget.spent():
            budget.unfinished.append(f"candidate {candidate.name} (round {round_.number}: screened, not fitted fully)")
            continue
        bar.update(bar.done, f"fitting {candidate.name}")
        fitted = round_.trial(candidate.name, candidate.fit.model.get(candidate.name), budget.part(SETTLE_SHARE),
                              quick=False)
        if fitted.fit.truncated:
            budget.unfinished.append(f"candidate {candidate.name} (round {round_.number}: its fit stopped at the "
                                     "budget)")
        out[k] = fitted
        acceptable += fitted.acceptable
        if acceptable == SHORTLIST and math.isinf(cutoff):
            cutoff = (1.0 + SCREEN_MARGIN) * candidate.score_after
    return sorted(out, key=lambda c: (c.screened, c.score_after, c.delta_bic))


def finalists(candidates: list[Candidate]) -> list[Candidate]:
    """The acceptable candidates to refit jointly before one is picked: the FINALISTS best by held-out score
    and, where not among them, the one with the fewest parameters among those with PARSIMONY of the best
    gain (empty: nothing acceptable)."""
    acceptable = sorted((c for c in candidates if c.acceptable), key=lambda c: c.score_after)
    if not acceptable:
        return []
    simplest = min((c for c in acceptable if c.gain >= PARSIMONY * acceptable[0].gain),
                   key=lambda c: (len(c.fit.free), c.score_after))
    return acceptable[:FINALISTS] + ([simplest] if simplest not in acceptable[:FINALISTS] else [])


def preferred(joints: list[tuple[Candidate, FitResult, float]], score: float) -> list[tuple[Candidate, FitResult, float]]:
    """Joint fits (candidate, fit, held-out score) in the order to take them from a model at held-out `score`:
    the fewest parameters among those with PARSIMONY of the best joint gain first, then by score."""
    if not joints:
        return []
    best = max(score ** 2 - after ** 2 for _, _, after in joints)
    close = [j for j in joints if score ** 2 - j[2] ** 2 >= PARSIMONY * best]
    return sorted(close, key=lambda j: (len(j[0].fit.free), j[2])) + \
        sorted((j for j in joints if j not in close), key=lambda j: j[2])


def rivals(lead: Candidate, candidates: list[Candidate]) -> list[tuple[Candidate, Candidate]]:
    """Pairs of acceptable candidates, each with fewer parameters than `lead` and no more together, that
    might explain as much (best held-out scores first, at most PAIRS), the better of each pair first."""
    size = len(lead.fit.free)
    smaller = sorted((c for c in candidates if c.acceptable and c is not lead and len(c.fit.free) < size),
                     key=lambda c: c.score_after)
    pairs = [(a, b) for i, a in enumerate(smaller) for b in smaller[i + 1:]
             if len(a.fit.free) + len(b.fit.free) <= size]
    return sorted(pairs, key=lambda p: -(p[0].gain + p[1].gain))[:PAIRS]

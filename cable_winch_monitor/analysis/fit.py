"""Fitting effect parameters to measurements: scipy least_squares on noise-normalised residuals.

Parameters are fitted in units of their declared `scale` (so a step means the same to
every parameter), within their bounds. Uncertainties come from the Jacobian at the
optimum, cov = (J^T J)^-1 scaled by the reduced chi-square where that exceeds 1 (the
model is not perfect); correlations from the same matrix. A parameter whose 1-sigma
uncertainty exceeds a quarter of its bounds' range, or that is correlated beyond 0.98
with another, is reported as not identified by the data, as are the effect's own
reasons (e.g. sheave friction without motion in both directions).

A parameter that ends at its bound (or within AT_BOUND, 1 %, of it) was
stopped by the bound, not by the data: its value is not an estimate and its Jacobian
uncertainty means nothing, so it is listed in `at_bound` and warned about, and the
effect is never reported as found. Values outside an effect's physical plausibility
(`Effect.implausible`, e.g. a mass change beyond 30 %) are listed and warned about too.

A fit may be capped (`max_evaluations`: a screening fit takes a few Gauss-Newton steps) or
stopped at a deadline: it then holds the best values met, not converged estimates.
`FitResult.refusals` says why an effect's fit cannot be taken as a finding: a value at a
bound, implausible, not converged, or not identified (none of its parameters is, or the
effect's own reason: sheave friction without motion both ways).
"""
from __future__ import annotations

import time
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from scipy.optimize import least_squares

from ..effects import Effect, PlantModel
from ..effects.base import Resolved
from .evaluate import Evaluator

MAX_EVALUATIONS = 60
# converged when a step lowers the chi-square by less than this share: at a good fit, hundredths of a sigma^2,
# what the estimates' own tolerance moves it by (smaller falls are its noise: steps kept being tried on them)
FTOL = 1e-5
UNIDENTIFIED_SPREAD = 0.1  # 1-sigma uncertainty / width of the bounds (a load cell on a slack cable: 0.12)
UNIDENTIFIED_CORRELATION = 0.98
AT_BOUND = 0.01     # a value within 1 % of a bound ended on it (bounds span decades: relative to the bound) ...
ZERO_BOUND = 1e-4   # ... or, for a bound at zero, within 1 % of this share of the bounds' width


@dataclass
class FitResult:
    """The model with fitted values, the free parameters, their 1-sigma uncertainties and correlations."""

    model: PlantModel
    free: list[tuple[str, Resolved]]
    values: np.ndarray
    sigmas: np.ndarray
    correlation: np.ndarray
    chi2: float
    count: int
    evaluations: int
    warnings: list[str] = field(default_factory=list)
    at_bound: list[str] = field(default_factory=list)      # "effect.parameter" stopped by a bound
    implausible: list[str] = field(default_factory=list)   # why a fitted value is physically implausible
    truncated: bool = False  # stopped at its deadline: the best values met so far, not converged
    converged: bool = True   # False: stopped by its deadline or its cap of evaluations
    unidentified: list[str] = field(default_factory=list)  # why an effect's parameters are not determined

    def honest(self, effect: str) -> bool:
        """The fitted values of `effect` are estimates: none ended on a bound, none is implausible."""
        return self.converged and not any(label.split(".")[0] == effect for label in self.at_bound) and \
            not any(reason.startswith(f"{effect}.") for reason in self.implausible)

    def refusals(self, effect: str) -> list[str]:
        """Why the fit of `effect` is no finding (empty: it is one): at a bound, implausible, not converged,
        not identified."""
        out = [f"{label} at its bound" for label in self.at_bound if label.split(".")[0] == effect]
        out += [reason for reason in self.implausible if reason.startswith(f"{effect}.")]
        out += [reason for reason in self.unidentified if reason.startswith(f"{effect}")]
        return out + ([] if self.converged else ["the fit did not converge"])

    @property
    def bic(self) -> float:
        """Bayesian information criterion with known noise: chi^2 + k ln n."""
        return self.chi2 + len(self.free) * np.log(max(self.count, 1))

    def params(self, effect: str) -> dict[str, dict[str, Any]]:
        """{parameter: {value, sigma, unit, at_bound}} of one effect (all its parameters; fixed ones without sigma)."""
        out = {}
        fitted = self.model.get(effect)
        assert fitted is not None, effect  # one of the model's effects
        for name, value in fitted.values.items():
            index = next((k for k, (e, p) in enumerate(self.free) if e == effect and p.name == name), None)
            unit = next(p.unit for p in type(fitted).parameters if p.name == name)
            out[name] = {"value": value, "sigma": None if index is None else float(self.sigmas[index]), "unit": unit,
                         "at_bound": f"{effect}.{name}" in self.at_bound}
        return out

    def correlations(self) -> dict[str, float]:
        """Pairwise correlations above 0.5 in magnitude, as 'effect.a ~ effect.b'."""
        labels = [f"{e}.{p.name}" for e, p in self.free]
        return {f"{labels[i]} ~ {labels[j]}": float(self.correlation[i, j]) for i in range(len(labels))
                for j in range(i + 1, len(labels)) if abs(self.correlation[i, j]) > 0.5}


def chi_square(model: PlantModel, evaluator: Evaluator, noise: np.ndarray) -> tuple[float, int]:
    """The squared residuals and length corrections [sigma], and the number of measured values."""
    z = evaluator.normalised(model, noise)
    return float(np.sum(z ** 2)), int(np.isfinite(evaluator.data.measured).sum())


class _OutOfTime(Exception):
    """The fit's deadline passed."""


def fit_effects(base: PlantModel, effects: Sequence[Effect], evaluator: Evaluator, noise: np.ndarray,
                deadline: float | None = None, max_evaluations: int = MAX_EVALUATIONS) -> FitResult:
    """Fit the fittable parameters of `effects` (added to `base`, others held) from their current values;
    at `deadline` (time.monotonic) the fit stops with the best values met so far (`truncated`), after
    `max_evaluations` steps (least_squares' max_nfev) it stops unconverged."""
    effects = [e if e.for_plant is not None else type(e)(e.values, base.plant) for e in effects]  # bounds of this plant
    free = [(e.name, p) for e in effects for p in e.fitted()]
    start = np.array([next(e for e in effects if e.name == name)[p.name] for name, p in free])
    scale = np.array([p.scale for _, p in free])
    lower = np.array([p.bounds[0] for _, p in free])
    upper = np.array([p.bounds[1] for _, p in free])

    def model_at(z: np.ndarray) -> PlantModel:
        values = start + z * scale
        updated = [e.replaced(**{p.name: float(v) for (name, p), v in zip(free, values) if name == e.name})
                   for e in effects]
        return base.with_effects(updated)

    best: list[tuple[float, np.ndarray, np.ndarray]] = []  # (chi-square, z, residuals) of the best call yet
    calls = [0]

    def residual(z: np.ndarray) -> np.ndarray:
        if deadline is not None and best and time.monotonic() > deadline:
            raise _OutOfTime
        calls[0] += 1
        fun = evaluator.normalised(model_at(z), noise)
        if not best or float(fun @ fun) < best[0][0]:
            best[:] = [(float(fun @ fun), z.copy(), fun)]
        return fun

    if not free:
        chi2, count = chi_square(base.with_effects(effects), evaluator, noise)
        return FitResult(base.with_effects(effects), [], np.zeros(0), np.zeros(0), np.zeros((0, 0)), chi2, count, 1)
    try:
        result = least_squares(residual, np.zeros(len(free)), bounds=((lower - start) / scale, (upper - start) / scale),
                               method="trf", x_scale=1.0, diff_step=1e-4, xtol=1e-6, ftol=FTOL,
                               max_nfev=max_evaluations)
    except _OutOfTime:
        return _truncated(model_at(best[0][1]), free, start + best[0][1] * scale, best[0][0], best[0][2].size,
                          calls[0])
    count = int(np.isfinite(evaluator.data.measured).sum())  # the corrections are not more data
    chi2 = float(np.sum(result.fun ** 2))
    information = result.jac.T @ result.jac
    covariance = np.linalg.pinv(information) * max(1.0, chi2 / max(count - len(free), 1))
    sigmas_z = np.sqrt(np.clip(np.diag(covariance), 0.0, None))
    with np.errstate(invalid="ignore", divide="ignore"):
        correlation = np.nan_to_num(covariance / np.outer(sigmas_z, sigmas_z))
    fit = FitResult(model_at(result.x), free, start + result.x * scale, sigmas_z * scale, correlation, chi2, count,
                    int(result.nfev), converged=result.status > 0)
    fit.at_bound = _at_bound(fit)
    fit.implausible = [reason for e in fit.model.effects if e.name in {name for name, _ in free}
                       for reason in e.implausible(base.plant)]
    identifiability = _identifiability(fit, effects, evaluator)
    fit.warnings = _bound_warnings(fit) + [f"implausible: {reason}" for reason in fit.implausible] + identifiability
    fit.unidentified = _unidentified(fit, effects, evaluator, identifiability)
    return fit


def _truncated(model: PlantModel, free: list[tuple[str, Resolved]], values: np.ndarray, chi2: float,
               count: int, evaluations: int) -> FitResult:
    """A fit stopped at its deadline: the best values met, no uncertainties."""
    fit = FitResult(model, free, values, np.full(len(free), np.nan), np.zeros((len(free), len(free))), chi2, count,
                    evaluations, truncated=True, converged=False)
    fit.warnings = [f"{', '.join(sorted({name for name, _ in free}))}: the fit stopped at the time budget after "
                    f"{evaluations} evaluations, before it converged; its values are the best met, not estimates"]
    return fit


def _at_bound(fit: FitResult) -> list[str]:
    """The free parameters whose value ended at, or within AT_BOUND of, a bound."""
    out = []
    for (name, p), value in zip(fit.free, fit.values):
        low, high = (AT_BOUND * max(abs(b), ZERO_BOUND * (p.bounds[1] - p.bounds[0])) for b in p.bounds)
        if value <= p.bounds[0] + low or value >= p.bounds[1] - high:
            out.append(f"{name}.{p.name}")
    return out


def _bound_warnings(fit: FitResult) -> list[str]:
    warnings = []
    for (name, p), value in zip(fit.free, fit.values):
        if f"{name}.{p.name}" in fit.at_bound:
            side = "lower" if value - p.bounds[0] <= p.bounds[1] - value else "upper"
            warnings.append(f"{name}.{p.name} = {value:.4g} {p.unit} ended at its {side} bound "
                            f"[{p.bounds[0]:.4g}, {p.bounds[1]:.4g}]: the bound, not the data, set it "
                            f"(not an estimate; widen plant.effect_bounds.{name}.{p.name} if the plant needs it)")
    return warnings


def _unidentified(fit: FitResult, effects: Sequence[Effect], evaluator: Evaluator, warnings: list[str]) -> list[str]:
    """Effects the bag does not determine: for the effect's own reason, or none of its free parameters
    identified (each with an uncertainty beyond UNIDENTIFIED_SPREAD of its range, or at a bound; parameters
    correlated with each other are still determined together)."""
    out = []
    for effect in effects:
        own = effect.warnings(evaluator.conditions)
        labels = [f"{name}.{p.name}" for name, p in fit.free if name == effect.name]
        undetermined = [label for label in labels if label in fit.at_bound
                        or any(w.startswith(f"{label}: not identified") for w in warnings)]
        if own:
            out.append(f"{effect.name}: not identified ({own[0].split(': ', 1)[-1]})")
        elif labels and len(undetermined) == len(labels) and not set(labels) <= set(fit.at_bound):
            out.append(f"{effect.name}: not identified (none of its parameters is determined by this bag)")
    return out


def _identifiability(fit: FitResult, effects: Sequence[Effect], evaluator: Evaluator) -> list[str]:
    warnings = []
    for effect in effects:
        warnings += effect.warnings(evaluator.conditions)
    for k, (name, p) in enumerate(fit.free):
        if f"{name}.{p.name}" in fit.at_bound:
            continue
        width = p.bounds[1] - p.bounds[0]
        if not np.isfinite(fit.sigmas[k]) or fit.sigmas[k] > UNIDENTIFIED_SPREAD * width:
            warnings.append(f"{name}.{p.name}: not identified by this bag (uncertainty {fit.sigmas[k]:.3g} {p.unit} "
                            f"against a range of {width:g} {p.unit})")
        for j in range(k + 1, len(fit.free)):
            if abs(fit.correlation[k, j]) > UNIDENTIFIED_CORRELATION:
                other = fit.free[j]
                warnings.append(f"{name}.{p.name} and {other[0]}.{other[1].name} cannot be told apart "
                                f"(correlation {fit.correlation[k, j]:+.3f})")
    return warnings

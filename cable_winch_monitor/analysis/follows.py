"""What the remaining error follows: rank the conditions of the recording a residual goes with.

When no library effect explains the error, the next question is what it moves with:
time, the payout, its speed or acceleration, the direction of motion, an extra input, a
field of some other topic in the bag. Each residual (each channel, and the load pins
together as their mean) is correlated with each of these regressors at the rows:

* Pearson's r for a continuous regressor (with the slope, in sigma and in the channel's unit per unit
  of the regressor: "+59 N per m" of payout is a rope weighing 59 N/m);
* for a discrete one (at most MAX_LEVELS integer values: the direction of motion, a flag,
  a mode) the correlation ratio eta, the share of the residual's spread explained by the
  level means (for two levels eta = |r|, and the sign of r is kept);
* for a product of a condition with the payout or with the rope's tension (`x payout`,
  `x tension`), the multiple correlation R of the residual with the product and the factor
  (an effect proportional to the rope's length -- thermal expansion, creep, elastic
  stretch -- leaves alpha (x - x0) l, with an offset x0 no one knows: temperature x payout
  fits it, temperature alone or the payout alone do not), signed by the product's coefficient,
  its slope in sigma per unit of the product.

A load pin's residual is tested against its own cable's payout, speed, direction and
tension where a condition is per cable (a robot moving sideways pays out on two winches
while hauling in on the others: the mean says it stands), other channels against the
means. The tension is the model's (measured minus residual): the measured one carries
the pin's own noise into the residual.

Regressors are ranked by their adjusted R^2 over the effective number of pairs: a product
spends one parameter more than its condition or its factor alone, and is no finding where
it does not explain more than either.

Residuals and regressors of a recording are smooth in time, so neighbouring rows are not
independent and a naive p-value would call nearly anything significant. The effective
number of independent pairs comes from Bartlett's formula over both autocorrelations,
1/n_eff = 1/n + (2/n) sum_j (1 - j/n) rho_x(j) rho_y(j), summed to n/5 lags (Pyper and
Peterman 1998), and the test (t for r, F for eta) uses n_eff. A finding needs |r| >=
MIN_R and p < ALPHA. No Bonferroni factor over the regressors: they are strongly
correlated with each other (time, payout and a drifting temperature all trend), so such
a factor would be far too strict; regressors that follow the residual about as closely
as the best one are named beside it, because the data cannot tell them apart.

Lags and derivatives of the regressors are not searched: the payout speed and
acceleration are regressors of their own.
"""
from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any, TypeGuard

import numpy as np
from scipy import stats

from ..channels import BUILTIN_CHANNELS, TENSION_CHANNELS, ChannelRegistry
from .bagfields import BagFields
from .data import Dataset

MIN_R = 0.5          # weaker correlations are not reported, however significant
ALPHA = 0.01         # per test, with the effective number of independent pairs
MIN_ROWS = 30        # fewer rows with both values: no test
MAX_ROWS = 3000      # longer series are thinned evenly (the estimate does not need more)
MAX_LEVELS = 5       # integer-valued regressors with at most this many values are discrete
LAG_SHARE = 0.2      # Bartlett's sum runs to this share of the series length
ALSO_WITHIN = 0.05   # regressors this close to the best |r| are named beside it
MAX_FINDINGS = 12
DIRECTION_WORDS = {-1.0: "hoisting", 0.0: "not yet moved", 1.0: "lowering"}
LOAD_PINS = "load-pin"
NOTHING = f"nothing: no residual follows any condition with |r| >= {MIN_R:g} at p < {ALPHA:g}"


@dataclass(frozen=True)
class Regressor:
    """A condition at every row: name (JSON key), words for sentences, unit, values (NaN: unknown), words
    for the levels of a discrete one, each cable's own values (rows, 4) where it is per cable, and for a
    product the condition and the factor it multiplies (tested beside it)."""

    name: str
    label: str
    unit: str
    values: np.ndarray
    levels: Mapping[float, str] | None = None
    cables: np.ndarray | None = None
    factors: tuple[Regressor, Regressor] | None = None

    def take(self, rows: np.ndarray) -> Regressor:
        return Regressor(self.name, self.label, self.unit, self.values[rows], self.levels,
                         None if self.cables is None else self.cables[rows],
                         None if self.factors is None else (self.factors[0].take(rows), self.factors[1].take(rows)))

    def at(self, channels: Sequence[str]) -> np.ndarray:
        """The values for a residual of these channels: a load pin's own cable's, the mean over the cables
        of several pins, else the common values."""
        cables = [TENSION_CHANNELS.index(c) for c in channels if c in TENSION_CHANNELS]
        if self.cables is None or len(cables) != len(channels):
            return self.values
        return self.cables[:, cables[0]] if len(cables) == 1 else _nanmean(self.cables[:, cables])

    def times(self, factor: Regressor) -> Regressor:
        """This condition times `factor` (the payout, the tension), per cable where either is."""
        cables = None
        if factor.cables is not None or self.cables is not None:
            mine = self.cables if self.cables is not None else self.values[:, None]
            cables = mine * (factor.cables if factor.cables is not None else factor.values[:, None])
        unit = f"{self.unit or 'unit'}*{factor.unit}"
        return Regressor(f"{self.name} x {factor.name}", f"{self.label} times {factor.label}", unit,
                         self.values * factor.values, None, cables, (self, factor))


@dataclass(frozen=True)
class Finding:
    """A residual that follows a regressor: r (or eta, `measure`), pairs n and independent pairs n_eff,
    p-value, slope [sigma per unit] or level means [sigma], the residual's sigma in `unit` (NaN where its
    channels differ), the regressors as close, and the sentence."""

    target: str
    channels: tuple[str, ...]
    regressor: str
    measure: str
    r: float
    n: int
    n_eff: float
    p: float
    slope: float | None
    level_means: dict[str, float]
    sigma: float
    unit: str
    also: tuple[tuple[str, float], ...]
    sentence: str

    def to_dict(self) -> dict[str, Any]:
        return {"channel": self.target, "channels": list(self.channels), "regressor": self.regressor,
                "measure": self.measure, "r": self.r, "n": self.n, "n_effective": self.n_eff, "p": self.p,
                "slope_sigma_per_unit": self.slope, "level_means_sigma": self.level_means,
                "sigma": self.sigma, "unit": self.unit,
                "slope": self.slope * self.sigma if self.slope is not None else None,
                "as_close": [{"regressor": name, "r": r} for name, r in self.also], "sentence": self.sentence}


def _direction(data: Dataset) -> np.ndarray:
    """+1 lowering, -1 hoisting, 0 not yet moved (or as many winches each way): the winches' common
    direction of motion."""
    return np.sign(data.directions.sum(axis=1))


def _on_rows(times: np.ndarray, t: np.ndarray, v: np.ndarray, discrete: bool) -> np.ndarray:
    """A series (t, v) at the row times: linear between samples, the last value for a discrete one,
    NaN outside the series' time span."""
    out = np.full(times.shape, np.nan)
    ok = np.isfinite(v)
    t, v = t[ok], v[ok]
    if t.size == 0:
        return out
    inside = (times >= t[0]) & (times <= t[-1])
    if discrete:
        out[inside] = v[np.clip(np.searchsorted(t, times[inside], side="right") - 1, 0, t.size - 1)]
    else:
        out[inside] = np.interp(times[inside], t, v)
    return out


def _is_discrete(values: np.ndarray) -> bool:
    finite = values[np.isfinite(values)]
    return finite.size > 0 and bool(np.all(finite == np.round(finite))) and np.unique(finite).size <= MAX_LEVELS


def regressors(data: Dataset, fields: BagFields | None = None, tensions: np.ndarray | None = None) -> list[Regressor]:
    """Every condition of a recording at the dataset's rows: time from the start, payout, speed and
    acceleration (means over the winches, and each winch's), direction of motion, the model's rope
    tensions (rows, 4) where given, each extra input the plant's effects declare (data.inputs) and each
    numeric field of the bag's other topics; then each of these times the payout and times the tension."""
    payout = Regressor("payout", "the payout", "m", data.lengths.mean(axis=1), cables=data.lengths)
    out = [Regressor("time", "time", "s", data.times - (data.times[0] if len(data) else 0.0)), payout,
           Regressor("speed", "the payout speed", "m/s", _nanmean(data.speeds), cables=data.speeds),
           Regressor("acceleration", "the payout acceleration", "m/s^2", _nanmean(data.accelerations),
                     cables=data.accelerations),
           Regressor("direction", "the direction of motion", "", _direction(data), DIRECTION_WORDS,
                     data.directions)]
    tension = None
    if tensions is not None and np.isfinite(tensions).any():
        tension = Regressor("tension", "the rope's tension", "N", _nanmean(tensions), cables=tensions)
        out.append(tension)
    for name, values in data.inputs.items():
        values = np.asarray(values, dtype=float)
        out.append(Regressor(name, name, "", values, {} if _is_discrete(values) else None))
    taken = {r.name for r in out}
    for name, (t, v) in (fields.series if fields else {}).items():
        if name not in taken:
            discrete = _is_discrete(v)
            out.append(Regressor(name, name, "", _on_rows(data.times, t, v, discrete), {} if discrete else None))
    factors = [payout] + ([tension] if tension is not None else [])
    return out + [r.times(f) for f in factors for r in out if r is not tension or f is not payout]


def _nanmean(values: np.ndarray) -> np.ndarray:
    finite = np.isfinite(values)
    count = finite.sum(axis=1)
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where(count > 0, np.where(finite, values, 0.0).sum(axis=1) / count, np.nan)


def autocorrelation(x: np.ndarray) -> np.ndarray:
    """rho(1..LAG_SHARE n) of a series (mean removed), by FFT (zero-padded past the last lag: no wrap)."""
    lags = max(1, int(LAG_SHARE * x.size))
    x = x - x.mean()
    spectrum = np.fft.rfft(x, size := 1 << int(np.ceil(np.log2(x.size + lags))))
    acf = np.fft.irfft(spectrum * np.conj(spectrum), size)[:lags + 1]
    return acf[1:] / acf[0] if acf[0] > 0 else np.zeros(lags)


def effective_pairs(rho_x: np.ndarray, rho_y: np.ndarray, n: int) -> float:
    """Bartlett's effective number of independent pairs of two autocorrelated series of n values, from
    their autocorrelations (see the module)."""
    j = np.arange(1, rho_x.size + 1)
    inverse = 1.0 / n + 2.0 / n * np.sum((1.0 - j / n) * rho_x * rho_y)
    return float(np.clip(1.0 / inverse if inverse > 0 else n, 3.0, n))


@dataclass
class _Test:
    regressor: Regressor
    measure: str
    r: float
    n: int
    n_eff: float
    p: float
    slope: float | None = None
    level_means: dict[str, float] = field(default_factory=dict)
    rank: float = 0.0  # adjusted R^2: the ranking key


def _adjusted(r2: float, n_eff: float, parameters: int) -> float:
    """R^2 adjusted for the parameters spent, over the effective number of pairs (the ranking key)."""
    return 1.0 - (1.0 - r2) * max(n_eff - 1.0, 1.0) / max(n_eff - parameters - 1.0, 1.0)


def _test(y: np.ndarray, regressor: Regressor, channels: Sequence[str], rho_y: dict[bytes, np.ndarray]) -> _Test | None:
    """r, eta or R of a residual y of `channels` with a regressor over the rows where both are known, and
    its p-value (`rho_y`: the residual's autocorrelation per set of rows, filled as needed)."""
    x = regressor.at(channels)
    main = np.column_stack([r.at(channels) for r in regressor.factors]) if regressor.factors else np.zeros((x.size, 0))
    both = np.isfinite(x) & np.isfinite(y) & np.isfinite(main).all(axis=1)
    x, y, main = x[both], y[both], main[both]
    if x.size < MIN_ROWS or np.ptp(x) == 0.0 or np.ptp(y) == 0.0:
        return None
    if x.size > MAX_ROWS:
        keep = np.linspace(0, x.size - 1, MAX_ROWS).round().astype(int)
        x, y, main = x[keep], y[keep], main[keep]
    key = both.tobytes()
    if key not in rho_y:
        rho_y[key] = autocorrelation(y)
    n_eff = effective_pairs(autocorrelation(x), rho_y[key], x.size)
    if regressor.factors is not None:
        return _product_test(x, y, main, regressor, n_eff)
    if regressor.levels is None or np.unique(x).size == 2:
        r = float(np.corrcoef(x, y)[0, 1])
        t = abs(r) * np.sqrt(max(n_eff - 2.0, 1.0) / max(1.0 - r * r, 1e-12))
        p = float(2.0 * stats.t.sf(t, max(n_eff - 2.0, 1.0)))
        test = _Test(regressor, "r", r, x.size, n_eff, p, None if regressor.levels is not None else
                     r * float(np.std(y) / np.std(x)), rank=_adjusted(r * r, n_eff, 1))
    else:
        levels = np.unique(x)
        means = np.array([y[x == level].mean() for level in levels])
        counts = np.array([(x == level).sum() for level in levels])
        eta2 = float(np.sum(counts * (means - y.mean()) ** 2) / np.sum((y - y.mean()) ** 2))
        k = levels.size
        dof = max(n_eff - k, 1.0)
        f_ratio = (eta2 / (k - 1)) / max((1.0 - eta2) / dof, 1e-12)
        test = _Test(regressor, "eta", float(np.sqrt(eta2)), x.size, n_eff, float(stats.f.sf(f_ratio, k - 1, dof)),
                     rank=_adjusted(eta2, n_eff, k - 1))
    if regressor.levels is not None:
        test.level_means = {_level_word(regressor, level): float(y[x == level].mean()) for level in np.unique(x)}
    return test


def _product_test(x: np.ndarray, y: np.ndarray, main: np.ndarray, regressor: Regressor,
                  n_eff: float) -> _Test | None:
    """The residual y against a product x = c f and its factor f (`main`: c and f): least squares y ~ a x + b f + d,
    i.e. a (c - c0) f with the offset c0 = -b / a free; R signed by a, the F-test of both over n_eff pairs,
    the slope a [sigma per unit of the product]. None where the product does not add to its parts: its
    adjusted R^2 must exceed that of c or f alone (a residual following the payout follows no product)."""
    factor = main[:, 1]
    design = np.column_stack([x, factor, np.ones_like(x)])
    coefficients, *_ = np.linalg.lstsq(design, y, rcond=None)
    spread = np.sum((y - y.mean()) ** 2)
    r2 = float(np.clip(1.0 - np.sum((y - design @ coefficients) ** 2) / spread, 0.0, 1.0))
    alone = max((float(np.corrcoef(part, y)[0, 1] ** 2) for part in main.T if np.ptp(part) > 0.0), default=0.0)
    rank = _adjusted(r2, n_eff, 2)
    if rank <= _adjusted(alone, n_eff, 1):
        return None
    dof = max(n_eff - 3.0, 1.0)
    f_ratio = (r2 / 2.0) / max((1.0 - r2) / dof, 1e-12)
    return _Test(regressor, "R", float(np.copysign(np.sqrt(r2), coefficients[0])), x.size, n_eff,
                 float(stats.f.sf(f_ratio, 2.0, dof)), float(coefficients[0]), rank=rank)


def _level_word(regressor: Regressor, level: float) -> str:
    return regressor.levels.get(level, f"{regressor.name} = {level:g}") if regressor.levels else \
        f"{regressor.name} = {level:g}"


def _words(target: str, channels: Sequence[str]) -> tuple[str, str]:
    """The residual in words and its verb: 'load-pin residuals follow', 'depth residual follows'."""
    if len(channels) > 1:
        return f"{target} residuals", "follow"
    name = channels[0]
    return (f"{name[len('tension_'):]} load-pin residual" if name in TENSION_CHANNELS else f"{name} residual"), \
        "follows"


def _sentence(target: str, channels: Sequence[str], best: _Test, also: list[_Test], scale: tuple[float, str]) -> str:
    subject, verb = _words(target, channels)
    sigma, unit = scale

    def amount(value: float, per: str = "") -> str:
        """'+0.118 sigma per m (+59.2 N per m)': in sigma, and in the channel's unit where known."""
        return f"{value:+.3g} sigma{per}" + (f" ({value * sigma:+.3g} {unit}{per})" if np.isfinite(sigma) and unit
                                             else "")

    text = f"{subject} {verb} {best.regressor.label}, {best.measure} = {best.r:.2f} (n = {best.n}"
    text += f", {best.n_eff:.0f} independent, p = {best.p:.1g})"
    if best.level_means:
        text += ": " + ", ".join(f"{word} {amount(mean)}" for word, mean in best.level_means.items())
    elif best.slope is not None:
        text += ": " + amount(best.slope, f" per {best.regressor.unit or 'unit'}")
    if also:
        text += "; as closely " + ", ".join(f"{t.regressor.label} ({t.measure} = {t.r:.2f})" for t in also)
    return text


def _significant(test: _Test | None) -> TypeGuard[_Test]:
    return test is not None and abs(test.r) >= MIN_R and test.p < ALPHA


def follows(z: np.ndarray, channels: Sequence[str], candidates: Sequence[Regressor],
            groups: Mapping[str, Sequence[str]] | None = None,
            scales: Mapping[str, tuple[float, str]] | None = None) -> list[Finding]:
    """What each residual follows, strongest first. `z`: (rows, channels) noise-normalised residuals in
    time order (NaN: not measured or not solved); `candidates`: regressors at the same rows; `groups`:
    targets made of several channels, residual = their mean (default: the load pins together); `scales`:
    each channel's sigma and unit, to say slopes in the channel's unit too. A channel of a group is named
    on its own only where it follows something the group does not."""
    if groups is None:
        pins = [c for c in channels if c in TENSION_CHANNELS]
        groups = {LOAD_PINS: pins} if len(pins) > 1 else {}
    targets = [(name, tuple(members)) for name, members in groups.items()] + [(c, (c,)) for c in channels]
    findings: list[Finding] = []
    group_regressor: dict[str, set[str]] = {}
    for target, members in targets:
        y = _nanmean(z[:, [channels.index(c) for c in members]])
        rho_y: dict[bytes, np.ndarray] = {}
        tests = sorted((t for t in (_test(y, r, members, rho_y) for r in candidates) if _significant(t)),
                       key=lambda t: -t.rank)
        if not tests:
            continue
        best = tests[0]
        if len(members) == 1 and best.regressor.name in group_regressor.get(members[0], set()):
            continue
        for member in members if len(members) > 1 else ():
            group_regressor.setdefault(member, set()).add(best.regressor.name)
        also = [t for t in tests[1:3] if t.rank >= best.rank - 2.0 * ALSO_WITHIN * np.sqrt(max(best.rank, 0.0))]
        shared = {(scales or {}).get(c, (np.nan, "")) for c in members}
        scale = shared.pop() if len(shared) == 1 else (np.nan, "")
        findings.append(Finding(target, members, best.regressor.name, best.measure, best.r, best.n, best.n_eff,
                                best.p, best.slope, best.level_means, float(scale[0]), scale[1],
                                tuple((t.regressor.name, t.r) for t in also),
                                _sentence(target, members, best, also, scale)))
    return sorted(findings, key=lambda f: -abs(f.r))[:MAX_FINDINGS]


def what_follows(data: Dataset, residuals: np.ndarray, noise: np.ndarray, rows: np.ndarray | None = None,
                 fields: BagFields | None = None, channels: ChannelRegistry = BUILTIN_CHANNELS) -> list[Finding]:
    """`follows` for residuals (rows, data.channels) with their channels' 1-sigma noise, at `rows` of a
    dataset (all rows if None), against every regressor of the dataset and the bag's other topics; the units
    those of `channels` (the plant model's)."""
    rows = np.arange(len(data)) if rows is None else rows
    tensions = np.full((len(data), 4), np.nan)
    if all(name in data.channels for name in TENSION_CHANNELS):  # the model's: measured minus residual
        pins = [data.channels.index(name) for name in TENSION_CHANNELS]
        tensions[rows] = data.measured[rows][:, pins] - residuals[:, pins]
    candidates = [r.take(rows) for r in regressors(data, fields, tensions)]
    scales = {name: (float(sigma), channels.get(name).unit) for name, sigma in zip(data.channels, noise)}
    return follows(residuals / noise, list(data.channels), candidates, scales=scales)

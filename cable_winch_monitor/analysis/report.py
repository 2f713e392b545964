"""Text and JSON (interface.md) renderings of compare, diagnose and fit results."""
from __future__ import annotations

from collections import Counter
from typing import Any

import numpy as np

from .compare import Comparison
from .diagnose import FOUND_SCORE, Diagnosis
from .evaluate import FAILED_PENALTY, ChannelStats
from .follows import NOTHING, Finding
from .refit import FitReport
from .unsolved import describe


def _channels(stats: dict[str, ChannelStats]) -> dict[str, Any]:
    return {name: s.to_dict() for name, s in stats.items()}


def _table(stats: dict[str, ChannelStats]) -> list[str]:
    lines = [f"{'channel':<17}{'samples':>8}{'RMS':>12}{'max |err|':>12}{'noise':>10}{'score':>8}"]
    lines += [f"{n:<17}{s.count:>8}{s.rms:>12.4g}{s.max_abs:>12.4g}{s.noise:>10.3g}{s.score:>8.3f}"
              for n, s in stats.items()]
    return lines


def _follows_lines(findings: list[Finding], notes: list[str]) -> list[str]:
    lines = ["what the remaining error follows:"]
    lines += [f"  {f.sentence}" for f in findings] or [f"  {NOTHING}"]
    return lines + [f"  {note}" for note in notes]


def _follows_json(findings: list[Finding], notes: list[str]) -> dict[str, Any]:
    return {"follows": [f.to_dict() for f in findings], "follows_notes": notes}


def _effect_values(model: Any) -> list[dict[str, Any]]:
    return [{"name": e.name, "params": dict(e.values), "enabled": True} for e in model.effects]


def _ill_conditioned(spans: list[Any]) -> list[str]:
    return [f"ill-conditioned: {s.describe()}" for s in spans]


def _unsolved(reasons: Counter[str], rows: int) -> list[str]:
    if not reasons:
        return []
    return [f"not solved: {describe(reasons, rows)}; their measurements count as {FAILED_PENALTY:g}-sigma misses"]


def compare_json(c: Comparison) -> dict[str, Any]:
    return {"bag": c.bag, "samples": len(c.data), "channels": _channels(c.channels), "score": c.score,
            "unsolved": {"rows": sum(c.unsolved.values()), "reasons": dict(c.unsolved)},
            "noise_source": c.noise_source, "failure_regions": c.regions, "effects": _effect_values(c.model),
            "ill_conditioned": [s.to_dict() for s in c.ill_conditioned], **_follows_json(c.follows, c.follows_notes)}


def compare_text(c: Comparison) -> str:
    sources = sorted(set(c.noise_source.values()))
    lines = [f"compared {c.bag}: {len(c.data)} measurement samples, model effects: "
             + (", ".join(repr(e) for e in c.model.effects) or "none (rigid ropes)"),
             *_table(c.channels), f"score {c.score:.3f} (1.0 = down to the sensor noise; noise: {', '.join(sources)})",
             *_unsolved(c.unsolved, len(c.data)), f"failure regions (|error| > 3 sigma): {len(c.regions) or 'none'}"]
    lines += [f"  {r['description']}" for r in c.regions[:10]]
    return "\n".join(lines + _ill_conditioned(c.ill_conditioned) + _follows_lines(c.follows, c.follows_notes))


def diagnose_json(d: Diagnosis, bag: str, samples: int) -> dict[str, Any]:
    final = d.final
    ranked = [c.to_dict() for c in d.ranking]
    for entry in ranked:  # selected effects: the values of the final joint fit
        if final is not None and final.model.get(entry["name"]) is not None and entry["selected"]:
            params = final.params(entry["name"])
            entry["params"] = {k: v["value"] for k, v in params.items()}
            entry["uncertainties"] = {k: None if v["at_bound"] else v["sigma"] for k, v in params.items()}
            entry["honest"] = final.honest(entry["name"])
        entry["found"] = d.found(entry["name"])
        entry["partial"] = entry["selected"] and d.partial
    return {"bag": bag, "samples": samples, "channels": _channels(d.channels), "score": d.ladder[0].score_heldout,
            "score_after": d.ladder[-1].score_heldout, "selected": d.selected,
            "found": [name for name in d.selected if d.found(name)], "partial": d.partial,
            "split": {"method": "interleaved blocks in time (30 % held out)", "training_rows": d.train_rows,
                      "held_out_rows": d.heldout_rows},
            "ladder": [{"added": None if s.removed else s.added, "removed": s.added if s.removed else None,
                        "score_train": s.score_train, "score_heldout": s.score_heldout, "bic": s.bic} for s in d.ladder],
            "refused": [r.to_dict() for r in d.refused],
            "correlations": final.correlations() if final else {}, "warnings": final.warnings if final else [],
            "ill_conditioned": [s.to_dict() for s in d.ill_conditioned], "budget": d.budget,
            "unsolved": {"rows": sum(d.unsolved.values()), "reasons": dict(d.unsolved)},
            "unfinished": d.unfinished, "untried": d.untried, "effects": ranked, **_follows_json(d.follows, d.follows_notes)}


def _value(name: str, v: dict[str, Any], short: bool = False) -> str:
    """A fitted value with its uncertainty, or marked as stopped by a bound or the time budget (none then)."""
    if v["at_bound"] or not np.isfinite(v["sigma"]):
        why = "at bound" if v["at_bound"] else "not converged"
        return f"{name}={v['value']:.4g} ({why})" if short else f"{name} = {v['value']:.5g} {v['unit']} ({why})"
    return f"{name}={v['value']:.4g}+-{v['sigma']:.2g}" if short else f"{name} = {v['value']:.5g} +- {v['sigma']:.2g} {v['unit']}"


def diagnose_text(d: Diagnosis) -> str:
    lines = [*_unsolved(d.unsolved, d.train_rows + d.heldout_rows),
             f"candidates, best first (fitted on {d.train_rows} training rows, scored on {d.heldout_rows} "
             "held-out rows from interleaved blocks; 'screened': a few steps on fewer rows, not fitted fully):",
             f"{'effect':<24}{'held-out score':>15}{'delta BIC':>12}  fitted"]
    for c in d.ranking:
        values = ", ".join(_value(k, v, short=True) for k, v in c.fit.params(c.name).items() if v["sigma"] is not None)
        mark = "  <- selected" if c.selected else "  (screened)" if c.screened else ""
        lines.append(f"{c.name:<24}{c.score_before:>7.3f}->{c.score_after:<7.3f}{c.delta_bic:>12.1f}  {values}{mark}")
    lines += [f"{name:<24}not tried: {reason}" for name, reason in d.untried.items()]
    lines += [f"refused in round {r.round}: {r.name} ({'; '.join(r.reasons)}): passed over, the ladder went on"
              for r in d.refused]
    lines.append("ladder: " + " -> ".join(f"{s.label()} ({s.score_heldout:.3f})" for s in d.ladder))
    if d.final is not None:
        for name in d.selected:
            effect = d.final.model.get(name)
            assert effect is not None  # a selected effect is in the final model
            values = ", ".join(_value(k, v) for k, v in d.final.params(name).items() if v["sigma"] is not None)
            verdict = "found" if d.found(name) else "partial explanation" if d.partial else \
                "not determined (see warnings)"
            lines.append(f"{verdict}: {type(effect).title} [{name}: {values}]")
        if d.partial:
            lines.append(f"partial: the final model still misses the held-out data ({d.ladder[-1].score_heldout:.3f} "
                         f"against {FOUND_SCORE:g} times the noise at most): what was added may stand in for an "
                         "effect the library lacks; see what the remaining error follows")
        lines += [f"correlation {k}: {v:+.3f}" for k, v in d.final.correlations().items()]
        lines += [f"warning: {w}" for w in d.final.warnings]
    else:
        lines.append(_nothing_found(d))
    if d.unfinished:
        lines.append(f"unfinished (the time budget of {d.budget:g} s was spent): {'; '.join(d.unfinished)}")
    return "\n".join(lines + _ill_conditioned(d.ill_conditioned) + _follows_lines(d.follows, d.follows_notes))


def _nothing_found(d: Diagnosis) -> str:
    """What is true when nothing was selected: no candidate helps, or the time budget stopped the ones that
    lowered the held-out error before their fits converged (never judged), or left candidates untried."""
    stopped = [c for c in d.ranking if c.fit.truncated and c.score_after < c.score_before]
    untried = sum(item.startswith("candidate ") for item in d.unfinished)
    if not stopped and not untried:
        return "found: nothing -- no candidate effect explains the data significantly better (held-out error and BIC)"
    why = [f"{', '.join(f'{c.name} ({c.score_before:.3f}->{c.score_after:.3f})' for c in stopped)} lowered the "
           "held-out error but stopped at the time budget before converging"] if stopped else []
    why += [f"{untried} candidate(s) were not tried or not fitted fully"] if untried else []
    return f"found: nothing within the time budget -- {'; '.join(why)}: give diagnose a larger --budget"


def fit_json(r: FitReport, bag: str, samples: int) -> dict[str, Any]:
    fit = r.fit
    return {"bag": bag, "samples": samples, "channels": _channels(r.after["held_out"].channels),
            "score": r.after["held_out"].score,
            "before": {part: {"score": s.score, "channels": _channels(s.channels)} for part, s in r.before.items()},
            "after": {part: {"score": s.score, "channels": _channels(s.channels)} for part, s in r.after.items()},
            "effects": [{"name": n, "params": {k: v["value"] for k, v in fit.params(n).items()},
                         "uncertainties": {k: None if v["at_bound"] else v["sigma"] for k, v in fit.params(n).items()},
                         "honest": fit.honest(n), "at_bound": fit.at_bound, "implausible": fit.implausible,
                         "score_before": r.before["held_out"].score, "score_after": r.after["held_out"].score,
                         "delta_bic": None, "selected": True} for n in r.effects],
            "correlations": fit.correlations(), "warnings": fit.warnings, "noise_source": r.noise_source}


def fit_text(r: FitReport) -> str:
    lines = []
    for name in r.effects:
        values = ", ".join(_value(k, v) if v["sigma"] is not None else f"{k} = {v['value']:.5g} {v['unit']}"
                           for k, v in r.fit.params(name).items())
        lines.append(f"fitted {name}: {values}")
    lines.append(f"{'channel':<17}{'train before':>14}{'train after':>13}{'held before':>13}{'held after':>12}")
    for name in r.after["held_out"].channels:
        row = [r.before["training"], r.after["training"], r.before["held_out"], r.after["held_out"]]
        cells = [f"{part.channels[name].score:.3f}" if name in part.channels else "-" for part in row]
        lines.append(f"{name:<17}{cells[0]:>14}{cells[1]:>13}{cells[2]:>13}{cells[3]:>12}")
    lines.append(f"{'score':<17}{r.before['training'].score:>14.3f}{r.after['training'].score:>13.3f}"
                 f"{r.before['held_out'].score:>13.3f}{r.after['held_out'].score:>12.3f}")
    lines += [f"correlation {k}: {v:+.3f}" for k, v in r.fit.correlations().items()]
    lines += [f"warning: {w}" for w in r.fit.warnings]
    return "\n".join(lines)

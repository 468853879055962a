"""The diagnosis as JSON (the ``phid diagnose --json`` contract docs/contracts.md states, and more)."""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any

from phid_ros.diagnose.outcome import Diagnosis, Score, parameter_errors
from phid_ros.model.parameters import GeneratorParameters

RMSE_DEFINITION = (
    "held-out scenarios, play-in driven by measured V_t, theta_t, P_m, V_f; per channel the residual's RMS with "
    "its white-noise share removed (estimated from the residual's first differences), divided by that channel's "
    "sensor-noise sigma; overall = RMS over omega, delta, i_d, i_q, p_e, q_e. 0 = nothing left but sensor noise."
)


def _channels(before: Score, after: Score) -> dict[str, Any]:
    return {
        c: {
            "rmse_before": before.channels[c].rmse,
            "rmse_after": after.channels[c].rmse,
            "unexplained_before": before.channels[c].unexplained,
            "unexplained_after": after.channels[c].unexplained,
        }
        for c in before.channels
    }


def to_json(
    d: Diagnosis, truth: GeneratorParameters | None = None, truth_effects: list | None = None
) -> dict[str, Any]:
    """The diagnosis as ``phid diagnose`` writes it; with the truth, the errors against it."""
    doc: dict[str, Any] = {
        "effects": _effects(d),
        "rmse_before": d.before.overall,
        "rmse_after": d.after.overall,
        "rmse_definition": RMSE_DEFINITION,
        "channels": _channels(d.before, d.after),
        "parameters": d.final.model.base,
        "uncertainty": d.uncertainty,
        "identifiable": d.identifiable,
        "held": d.held,
        "parameters_identified": d.identified,
        "parameters_identified_at_bound": list(d.identified_at_bound),
        "parameters_base_refit": d.base_fit.model.base,
        "fit": {"chi2_before": d.base_fit.chi2, "chi2_after": d.final.chi2, "samples": d.final.n},
        "rounds": _rounds(d),
        "fit_scenarios": [w.name for w in d.fit_windows],
        "heldout_scenarios": [w.name for w in d.heldout_windows],
        "noise_sigma": d.sigma,
        "problems": d.problems,
        "seconds": d.seconds,
    }
    if truth is not None:
        doc |= _against_truth(d, truth)
    if truth_effects is not None:
        doc["truth_effects"] = truth_effects
    return doc


def _effects(d: Diagnosis) -> list[dict[str, Any]]:
    """Each named effect as it was accepted: its values, stds, presence and the gap it closed."""
    effects = []
    prev = d.before
    stds = d.final.effect_std or [{} for _ in d.final.model.effects]
    for (cand, values), (name, sc), std in zip(d.final.model.effects, d.steps, stds):
        trial = next(t for r in d.rounds for t in r.trials if t.accepted and t.candidate == name)
        effects.append(
            {
                "name": name,
                "parameters": dict(values),
                "parameters_std": dict(std),
                # false where the data do not determine it (diagnose.determinability.determined)
                "identifiable": dict(d.effects_identifiable.get(name, {})),
                "presence_sigma": trial.presence,
                "rmse_before": prev.overall,
                "rmse_after": sc.overall,
                "delta_bic": trial.delta_bic,
                "heldout_gain": trial.heldout_gain,
                "signature": cand.signature,
            }
        )
        prev = sc
    return effects


def _rounds(d: Diagnosis) -> list[dict[str, Any]]:
    """Each round's trials: every candidate tried, its fit and its verdict."""
    return [
        {
            "named": r.chosen,
            "trials": [
                {
                    "candidate": t.candidate,
                    "settings": t.settings,
                    "parameters": t.fit.model.effect_values().get(t.candidate) if t.fit else None,
                    "screened_chi2": t.screened_chi2,
                    "chi2": t.fit.chi2 if t.fit else None,
                    "delta_bic": None if math.isnan(t.delta_bic) else t.delta_bic,
                    "heldout_rmse": t.heldout.overall if t.heldout else None,
                    "heldout_gain": None if math.isnan(t.heldout_gain) else t.heldout_gain,
                    "presence_sigma": t.presence,
                    "accepted": t.accepted,
                }
                for t in r.trials
            ],
        }
        for r in d.rounds
    ]


def _against_truth(d: Diagnosis, truth: GeneratorParameters) -> dict[str, Any]:
    """The truth, and each parameter set's errors against it (per cent)."""
    doc: dict[str, Any] = {"truth": truth.as_dict()}
    doc["errors_pct"] = {
        "identified": parameter_errors(d.identified, truth),
        "base_refit": parameter_errors(d.base_fit.model.base, truth),
        "after": parameter_errors(d.final.model.base, truth),
    }
    doc["mean_abs_error_pct"] = {k: _mean_abs(e) for k, e in doc["errors_pct"].items()}
    # D is a few per cent of this class of plant's damping and output error places it within
    # about +-15 % whatever the model: the mean without it shows what the other seven did
    doc["mean_abs_error_pct_without_D"] = {
        k: _mean_abs({n: v for n, v in e.items() if n != "D"}) for k, e in doc["errors_pct"].items()
    }
    return doc


def is_determined(doc: Mapping[str, Any], name: str) -> bool:
    """Whether the diagnosis (its JSON) determined base parameter ``name``; older JSON: yes."""
    return bool(doc.get("identifiable", {}).get(name, True))


def effect_determined(effect: Mapping[str, Any], name: str) -> bool:
    """Whether the diagnosis determined parameter ``name`` of one of its effects (JSON); older JSON: yes."""
    return bool(effect.get("identifiable", {}).get(name, True))


def _mean_abs(errors: dict[str, float]) -> float:
    return sum(abs(v) for v in errors.values()) / len(errors)

"""The estimator's front door: the equilibrium state that best explains every measurement, the cable lengths too.

`estimate` (one sample) and `estimate_batch` (many at once) search the taut sets by Gauss-Newton on the
equilibrium manifold (fusion.py) from the model's own `forward_kinematics`; the measurements are
`Observation`s of the state (`States`); the model's expected error at each sample is a `Prior`, kept up to
date by `ModelError` from the samples it has seen; `chi_square_threshold` gates a sensor's agreement.
`Problem` and `Rows` (the stacked search) are for those who extend it: the monitor's screening of faults,
the tracked parameters' derivatives.
"""
from .estimation import BatchEstimate, Estimate, estimate, estimate_batch, forward_kinematics, unfused
from .fusion import Problem, Rows, implied_lengths, prior_jacobian, reduced_normal, residuals_and_balance
from .gate import DEFAULT_PROBABILITY, DEFAULT_THRESHOLDS, chi_square_threshold
from .model_error import ErrorState, ModelError, chain
from .observations import Observation, States, forward_differences
from .prior import Prior, whitening

__all__ = ["DEFAULT_PROBABILITY", "DEFAULT_THRESHOLDS", "BatchEstimate", "ErrorState", "Estimate", "ModelError",
           "Observation", "Prior", "Problem", "Rows", "States", "chain", "chi_square_threshold", "estimate",
           "estimate_batch", "forward_differences", "forward_kinematics", "implied_lengths", "prior_jacobian",
           "reduced_normal", "residuals_and_balance", "unfused", "whitening"]

"""Types of the compiled solvers' inner loops (compiled.pyx)."""
import numpy as np

def newton_taut_set(lengths: np.ndarray, rotation: np.ndarray, position: np.ndarray, mu: np.ndarray,
                    loads: np.ndarray, steps: np.ndarray, taut: np.ndarray, attachments: np.ndarray,
                    cog: np.ndarray, anchors: np.ndarray, scale: float, tolerance: np.ndarray, max_steps: int,
                    converged: np.ndarray, turn_limit: float, shift_limit: float,
                    minimum_norm: bool = False) -> None: ...
def equilibrium_terms(rotation: np.ndarray, position: np.ndarray, mu: np.ndarray, taut: np.ndarray,
                      weight: np.ndarray, lengths: np.ndarray, anchors: np.ndarray, attachments: np.ndarray,
                      cog: np.ndarray, loads: np.ndarray, axial_stiffness: np.ndarray, rope_weight: float,
                      scale: float, sigma: float, residual: np.ndarray, constraint: np.ndarray,
                      jacobian: np.ndarray, balance: np.ndarray, with_jacobian: bool) -> None: ...
def kkt_systems(jacobian: np.ndarray, residual: np.ndarray, balance: np.ndarray, slack: np.ndarray, mu: np.ndarray,
                eps: float, system: np.ndarray, gradient: np.ndarray) -> None: ...
def kkt_steps(system: np.ndarray, rhs: np.ndarray, step: np.ndarray, singular: np.ndarray) -> None: ...
def kkt_responses(system: np.ndarray, rhs: np.ndarray, out: np.ndarray, singular: np.ndarray) -> None: ...
def whiten_rows(sample: np.ndarray, residual: np.ndarray, jacobian: np.ndarray, with_jacobian: bool,
                length_white: np.ndarray, pin_white: np.ndarray, pins: np.ndarray, pin_scale: np.ndarray,
                measured: np.ndarray, expected: np.ndarray) -> None: ...
def gauss_newton_verdict(live: np.ndarray, cost: np.ndarray, constraint: np.ndarray, reach: np.ndarray,
                         previous: np.ndarray, last: np.ndarray, scale: np.ndarray, settled: np.ndarray,
                         rotation: np.ndarray, position: np.ndarray, mu: np.ndarray, balance_tol: float,
                         cost_tol: float, step_tol: float, kept: np.ndarray, retry: np.ndarray) -> tuple[int, int]: ...
def gauss_newton_advance(live: np.ndarray, step: np.ndarray, retry: np.ndarray, reach: np.ndarray, scale: np.ndarray,
                         last: np.ndarray, steps: np.ndarray, settled: np.ndarray, rotation: np.ndarray,
                         position: np.ndarray, mu: np.ndarray, turn_limit: float, shift_limit: float, step_tol: float,
                         out: np.ndarray) -> int: ...
def active_set_rows(lengths: np.ndarray, rotation: np.ndarray, position: np.ndarray, mu: np.ndarray,
                    active: np.ndarray, loads: np.ndarray, steps: np.ndarray, done: np.ndarray,
                    attachments: np.ndarray, cog: np.ndarray, anchors: np.ndarray, scale: float,
                    tolerance: np.ndarray, max_steps: int, rounds: int, max_turn: float, rounding: np.ndarray,
                    tension_tol: float, turn_limit: float, shift_limit: float) -> None: ...
def slack_pin_bounds(samples: np.ndarray, codes: np.ndarray, ropes: np.ndarray, deviation: np.ndarray,
                     covariance: np.ndarray, bound: np.ndarray) -> None: ...
def elastic_newton_rows(lengths: np.ndarray, rotation: np.ndarray, position: np.ndarray, loads: np.ndarray,
                        stiffness: np.ndarray, weight: np.ndarray, attachments: np.ndarray, cog: np.ndarray,
                        anchors: np.ndarray, scale: float, max_steps: int, tol: float, rounding_tol: float,
                        step_turn: float, tensions: np.ndarray, stretch: np.ndarray, steps: np.ndarray,
                        done: np.ndarray) -> None: ...

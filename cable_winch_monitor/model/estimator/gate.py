"""Chi-square gate thresholds: does a sensor's reading agree with the estimate within reason?

As ROS sensor-fusion nodes do (robot_localization's rejection thresholds), a sensor's
innovation y (measured minus predicted, one entry per channel: four load pins, roll and
pitch, ...) is weighed by its covariance S: d^2 = y^T S^-1 y follows a chi-square
distribution with as many degrees of freedom as channels when the sensor and the model
agree. A reading with d^2 beyond the chi-square quantile of the gate probability is
rejected (`monitor.estimator` screens every sample's sensors so).
"""
from __future__ import annotations

from functools import lru_cache

DEFAULT_PROBABILITY = 0.999
# chdtri(k, 1 - DEFAULT_PROBABILITY) for k = 1..16 channels (a sample's four lengths and up to twelve readings),
# to the bit as scipy gives them (a test holds them to it): every sample gates its sensors at the default
# probability, and scipy.special takes 0.2 s to import, a twentieth of a 10,000-sample replay.
DEFAULT_THRESHOLDS = (10.827566170662733, 13.815510557964274, 16.26623619623813, 18.46682695290317,
                      20.515005652432873, 22.457744484825323, 24.321886347856854, 26.12448155837614,
                      27.877164871256568, 29.58829844507442, 31.264133620239985, 32.90949040736021,
                      34.52817897487089, 36.12327368039813, 37.69729821835383, 39.252354790768464)


@lru_cache(maxsize=64)  # every sample gates its sensors: the quantile is computed once per dof
def chi_square_threshold(dof: int, probability: float = DEFAULT_PROBABILITY) -> float:
    """The chi-square quantile a consistent sensor of `dof` channels stays below with `probability`."""
    if dof < 1 or not 0.0 < probability < 1.0:
        raise ValueError(f"gate needs dof >= 1 and 0 < probability < 1, got dof={dof}, probability={probability}")
    if probability == DEFAULT_PROBABILITY and dof <= len(DEFAULT_THRESHOLDS):
        return DEFAULT_THRESHOLDS[dof - 1]
    from scipy.special import chdtri  # the inverse survival function; scipy.stats takes 2 s to import

    return float(chdtri(dof, 1.0 - probability))

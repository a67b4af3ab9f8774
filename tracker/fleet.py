"""The width error of the data at hand, learned from the vehicles the tracker has measured whole.

The vehicle classes (``tracker.config.VehicleClass``, ``BirthConfig.classes``) give an unmeasured
length its prior from the measured width (``tracker.extent.class_length_prior``). Their widths are
bodies' (mirrors excluded): what a lidar's rectangle of a vehicle shows. Widths from other sources
stray from the body's: boxes drawn around the mirrors, the labels of a video-tracking dataset (NGSIM's
US-101 and Lankershim recordings put many passenger cars at 2.1-2.6 m), a camera detector's boxes.
Read as bodies, such a width makes a car a van or a truck, and its length prior metres too long.
``BirthConfig.width_error_std`` widens every class's width by that error; ``WidthError`` learns it
from the traffic being tracked.

Each vehicle the tracker has measured whole (a reported track whose width and length standard
deviations are at most ``MEASURED_WIDTH_STD`` and ``MEASURED_LENGTH_STD``: a face and a side both seen)
gives a pair ``(w_i, l_i)`` with variances ``(u_i, v_i)`` (its latest, one pair per label). The width
error is the maximum-likelihood ``sigma_e`` on the grid ``GRID`` of the classes' joint density of the
pairs::

    log L(sigma_e) = sum_i log sum_c share_c N(w_i; w_c, var_w_c + sigma_e^2 + u_i) N(l_i; l_c, var_l_c + v_i)

once at least ``BirthConfig.width_error_vehicles`` pairs are known and the data favour it over the
configured ``width_error_std`` by ``EVIDENCE`` (else, and with ``width_error_vehicles`` None, the
configured one). The length keeps the classes' own spread: only the width's convention
differs between sources. A vehicle measured whole does not use the classes' prior, so the estimate
does not feed back into its own samples.
"""

from __future__ import annotations

import numpy as np

from tracker.config import BirthConfig
from tracker.extent import class_arrays
from tracker.motion import LENGTH, WIDTH

#: Candidate width errors (m): 0 (bodies) to 0.5 m (a box around a pickup's mirrors) in 2.5 cm steps.
GRID = np.round(np.arange(0.0, 0.5 + 1e-9, 0.025), 3)
#: The learned width error replaces the configured one only where its log-likelihood exceeds the
#: configured one's by at least this (nats; 3: a likelihood ratio of 20, strong evidence): a few vehicles
#: whose widths lie near the classes' bodies do not move it.
EVIDENCE = 3.0
#: A width whose standard deviation is at most this (m) is measured: a face seen whole (the birth's
#: fitted width has ``BirthConfig.fit_width_std``, 0.1 m, and an unseen one ``width_std``, 0.3 m).
MEASURED_WIDTH_STD = 0.08
#: A length whose standard deviation is at most this (m) is measured: a side seen whole (an unseen one
#: keeps at least ``UNMEASURED`` x ``BirthConfig.length_std``, 0.9 m).
MEASURED_LENGTH_STD = 0.3


class WidthError:
    """The estimator of ``BirthConfig.width_error_std`` from the vehicles measured whole (module
    docstring). ``observe`` each frame's tracks; ``value`` is the width error to use (m)."""

    def __init__(self, birth: BirthConfig) -> None:
        self.default = float(birth.width_error_std)
        self.min_vehicles = birth.width_error_vehicles
        # the classes' shares, lengths, length variances, widths and body width variances (C,)
        self._classes = class_arrays(birth.classes, 0.0) if birth.classes else None
        self._pairs: dict[int, tuple[float, float, float, float]] = {}  # label -> (w, l, var w, var l)
        self._value = self.default
        self._errors = np.append(GRID, self.default)
        self._stale = False

    @property
    def vehicles(self) -> int:
        """How many vehicles have been measured whole."""
        return len(self._pairs)

    @property
    def value(self) -> float:
        """The width error (m): the maximum-likelihood one of the pairs once there are ``min_vehicles``
        and it beats the configured one by ``EVIDENCE``, else the configured one."""
        if self._stale:
            self._stale = False
            if self.min_vehicles is not None and len(self._pairs) >= self.min_vehicles and self._classes is not None:
                ll = self.log_likelihood(self._errors)  # the grid, then the configured error
                best = int(np.argmax(ll[:-1]))
                self._value = float(GRID[best]) if ll[best] - ll[-1] >= EVIDENCE else self.default
        return self._value

    def observe(self, labels: np.ndarray, means: np.ndarray, covs: np.ndarray) -> None:
        """Take the tracks ``labels (K,)`` with states ``means (K, D)`` and covariances ``covs (K, D, D)``:
        those whose width and length are both measured replace their label's pair."""
        if self.min_vehicles is None or not len(labels):
            return
        var_w, var_l = covs[:, WIDTH, WIDTH], covs[:, LENGTH, LENGTH]
        whole = (var_w <= MEASURED_WIDTH_STD**2) & (var_l <= MEASURED_LENGTH_STD**2)
        for k in np.flatnonzero(whole).tolist():
            self._pairs[int(labels[k])] = (float(means[k, WIDTH]), float(means[k, LENGTH]), float(var_w[k]),
                                           float(var_l[k]))
            self._stale = True

    def log_likelihood(self, errors: np.ndarray = GRID) -> np.ndarray:
        """``log L(sigma_e)`` (module docstring) at each of ``errors (G,)`` (m; default ``GRID``), ``(G,)``."""
        share, length, length_var, width, width_var = self._classes
        pairs = np.array(list(self._pairs.values()), dtype=float).reshape(-1, 4)
        w, l, u, v = (pairs[:, j, None] for j in range(4))  # (N, 1) each
        var_l = length_var + v  # (N, C)
        joint = np.log(share) - 0.5 * (np.log(2.0 * np.pi * var_l) + (l - length) ** 2 / var_l)
        var_w = width_var + np.square(errors)[:, None, None] + u  # (G, N, C)
        joint = joint - 0.5 * (np.log(2.0 * np.pi * var_w) + (w - width) ** 2 / var_w)
        top = joint.max(axis=2, keepdims=True)  # logsumexp over the classes, without scipy's call overhead
        return (top[..., 0] + np.log(np.exp(joint - top).sum(axis=2))).sum(axis=1)

"""Study variants: named tracker configurations used by ``eot run --variant`` and the Monte Carlo.

Each variant is a ``tracker.TrackerConfig`` of the same machinery (DESIGN.md "tracker.Tracker"):

- ``curvilinear-fused`` (default): the paper's tracker, state ``[s, n, v, xi, xi_dot, L, W]``,
  exact Frenet motion, lidar + radar;
- ``curvilinear-lidar``: the same without radar (lidar only);
- ``cartesian-fused``: the same extended-object tracker with a Cartesian state in G, lidar + radar;
- ``paper-motion``: ``curvilinear-fused`` with the paper's flat constant-turn motion model in (s, n)
  instead of the exact Frenet kinematics.

A scenario's ``[tracker]`` table is applied on top of the variant's configuration by the runner.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable

from tracker import TrackerConfig

#: The default variant.
DEFAULT_VARIANT = "curvilinear-fused"


def _paper_motion() -> TrackerConfig:
    base = TrackerConfig.for_variant("curvilinear-fused")
    return dataclasses.replace(base, motion=dataclasses.replace(base.motion, model="paper"))


_VARIANTS: dict[str, tuple[str, Callable[[], TrackerConfig]]] = {
    "curvilinear-fused": (
        "the paper's tracker: curvilinear state, exact Frenet motion, lidar + radar",
        lambda: TrackerConfig.for_variant("curvilinear-fused"),
    ),
    "curvilinear-lidar": (
        "curvilinear state, lidar only",
        lambda: TrackerConfig.for_variant("curvilinear-lidar"),
    ),
    "cartesian-fused": (
        "the same extended-object tracker with a Cartesian state, lidar + radar",
        lambda: TrackerConfig.for_variant("cartesian-fused"),
    ),
    "paper-motion": (
        "curvilinear-fused with the paper's flat constant-turn motion model",
        _paper_motion,
    ),
}

#: Names of the known variants, default first.
VARIANTS: tuple[str, ...] = tuple(_VARIANTS)


class UnknownVariantError(ValueError):
    """A variant name that is not one of ``VARIANTS``; the message lists the choices."""


def describe(name: str) -> str:
    """One-line description of the variant ``name``."""
    return _VARIANTS[check_variant(name)][0]


def check_variant(name: str) -> str:
    """``name`` if it is a known variant; else ``UnknownVariantError`` listing the choices."""
    if name not in _VARIANTS:
        raise UnknownVariantError(f"unknown variant {name!r}; choose one of: {', '.join(VARIANTS)}")
    return name


def variant_config(name: str) -> TrackerConfig:
    """The ``TrackerConfig`` of the variant ``name`` (see the module docstring)."""
    return _VARIANTS[check_variant(name)][1]()


__all__ = ["DEFAULT_VARIANT", "VARIANTS", "UnknownVariantError", "check_variant", "describe", "variant_config"]

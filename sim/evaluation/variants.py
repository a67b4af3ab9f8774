"""Study variants: named trackers used by ``eot run --variant``, the Monte Carlo and ``eot compare``.

Most variants are a ``tracker.TrackerConfig`` of the same machinery (docs/architecture.md "tracker.Tracker"):

- ``curvilinear-fused`` (default): the paper's tracker, state ``[s, n, v, xi, xi_dot, L, W]``,
  exact Frenet motion, lidar + radar;
- ``curvilinear-lidar``: the same without radar (lidar only);
- ``cartesian-fused``: the same extended-object tracker with a Cartesian state in G, lidar + radar;
- ``paper-motion``: ``curvilinear-fused`` with the paper's flat constant-turn motion model in (s, n)
  instead of the exact Frenet kinematics;
- ``paper``: everything as the paper wrote it: the flat motion model *and* the paper's Euler
  conversion (Algorithm 1) in the measurement model (``MeasurementConfig.conversion = "euler"``);
- ``point-gnn``: the point-object GNN tracker with a UKF in curvilinear coordinates on cluster
  centroids (``TrackerConfig.for_variant("point-fused")``; the paper's earlier work): no extent;
- ``stonesoup-gmphd``: Stone Soup's GM-PHD with its UKF on the same cluster centroids
  (``sim.baselines.stonesoup_gmphd``; optional extra ``baselines``): no extent, lidar only.

A variant whose optional dependency this installation lacks (Stone Soup for ``stonesoup-gmphd``) stays
registered; building it raises ``VariantUnavailableError`` (a ``ValueError``) saying what to install,
and ``probe_variant`` reports that reason without running anything, so a study can skip the variant.
Any other failure to build a variant is a bug, not an unavailable variant: ``probe_variant`` lets it
propagate.

A scenario's ``[tracker]`` table is applied on top of the variant's configuration by the runner.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

from tracker import Road, TrackerConfig

#: The default variant.
DEFAULT_VARIANT = "curvilinear-fused"


class UnknownVariantError(ValueError):
    """A variant name that is not one of ``VARIANTS``; the message lists the choices."""


class VariantUnavailableError(ValueError):
    """A registered variant that this installation cannot build because an optional dependency is
    missing (raised where its import fails); the message says what to install."""


@dataclass(frozen=True)
class Variant:
    """A registered variant: ``description`` (one line), ``config()`` (its ``TrackerConfig``),
    ``factory`` (a picklable ``tracker_factory(road, config)``; ``None``: ``tracker.Tracker``) and
    ``extent`` (whether its tracks estimate length and width; point trackers do not)."""

    name: str
    description: str
    config: Callable[[], TrackerConfig]
    factory: Callable[[Road, TrackerConfig], Any] | None = None
    extent: bool = True


def _paper_motion() -> TrackerConfig:
    base = TrackerConfig.for_variant("curvilinear-fused")
    return dataclasses.replace(base, motion=dataclasses.replace(base.motion, model="paper"))


def _paper() -> TrackerConfig:
    base = _paper_motion()
    return dataclasses.replace(base, measurement=dataclasses.replace(base.measurement, conversion="euler"))


def _stonesoup_config() -> TrackerConfig:
    """The settings the Stone Soup baseline shares with our tracker (clustering, detection, reduction)."""
    return TrackerConfig.for_variant("curvilinear-lidar")


def stonesoup_factory(road: Road, config: TrackerConfig) -> Any:
    """``tracker_factory`` of ``stonesoup-gmphd`` (imports the baseline, and Stone Soup, on first use);
    ``VariantUnavailableError`` when Stone Soup is not installed."""
    from sim.baselines.stonesoup_gmphd import MissingBaselineError, StoneSoupGMPHD

    try:
        return StoneSoupGMPHD(road, config)
    except MissingBaselineError as exc:
        raise VariantUnavailableError(str(exc)) from None


_REGISTRY: tuple[Variant, ...] = (
    Variant("curvilinear-fused", "the paper's tracker: curvilinear state, exact Frenet motion, lidar + radar",
            lambda: TrackerConfig.for_variant("curvilinear-fused")),
    Variant("curvilinear-lidar", "curvilinear state, lidar only", lambda: TrackerConfig.for_variant("curvilinear-lidar")),
    Variant("cartesian-fused", "the same extended-object tracker with a Cartesian state, lidar + radar",
            lambda: TrackerConfig.for_variant("cartesian-fused")),
    Variant("paper-motion", "curvilinear-fused with the paper's flat constant-turn motion model", _paper_motion),
    Variant("paper", "as the paper wrote it: flat constant-turn motion and the Euler conversion (Algorithm 1)", _paper),
    Variant("point-gnn", "point-object GNN with a curvilinear UKF on cluster centroids, lidar + radar (no extent)",
            lambda: TrackerConfig.for_variant("point-fused"), extent=False),
    Variant("stonesoup-gmphd", "Stone Soup's GM-PHD + UKF on cluster centroids, lidar only (no extent)",
            _stonesoup_config, factory=stonesoup_factory, extent=False),
)
_VARIANTS: dict[str, Variant] = {v.name: v for v in _REGISTRY}

#: Names of the registered variants, default first.
VARIANTS: tuple[str, ...] = tuple(_VARIANTS)


def check_variant(name: str) -> str:
    """``name`` if it is a registered variant; else ``UnknownVariantError`` listing the choices."""
    if name not in _VARIANTS:
        raise UnknownVariantError(f"unknown variant {name!r}; choose one of: {', '.join(VARIANTS)}")
    return name


def get_variant(name: str) -> Variant:
    """The registered ``Variant`` called ``name``."""
    return _VARIANTS[check_variant(name)]


def describe(name: str) -> str:
    """One-line description of the variant ``name``."""
    return get_variant(name).description


def variant_config(name: str) -> TrackerConfig:
    """The ``TrackerConfig`` of the variant ``name`` (see the module docstring);
    ``VariantUnavailableError`` when this installation cannot configure it."""
    return get_variant(name).config()


def variant_factory(name: str) -> Callable[[Road, TrackerConfig], Any] | None:
    """The variant's own ``tracker_factory`` (``None``: the package's ``tracker.Tracker``)."""
    return get_variant(name).factory


def estimates_extent(name: str) -> bool:
    """Whether the variant's tracks estimate length and width (``False`` for point trackers)."""
    return get_variant(name).extent


def make_tracker(name: str, road: Road, config: TrackerConfig | None = None) -> Any:
    """The tracker of variant ``name`` on ``road`` (``config`` default: the variant's)."""
    config = variant_config(name) if config is None else config
    factory = variant_factory(name)
    if factory is not None:
        return factory(road, config)
    from tracker import Tracker

    return Tracker(road, config)


def probe_variant(name: str) -> str | None:
    """``None`` when the variant can be built here; the one-line reason when it cannot because an
    optional dependency is missing (``VariantUnavailableError``). Any other exception of its
    configuration or tracker propagates. Builds the tracker on a short straight road; runs nothing."""
    check_variant(name)
    road = Road.from_curvature([(200.0, 0.0, 0.0)], start=(0.0, 0.0, 0.0), lanes=2)
    try:
        make_tracker(name, road)
    except VariantUnavailableError as exc:
        return " ".join(str(exc).split()) or type(exc).__name__
    return None


__all__ = [
    "DEFAULT_VARIANT",
    "VARIANTS",
    "UnknownVariantError",
    "Variant",
    "VariantUnavailableError",
    "check_variant",
    "describe",
    "estimates_extent",
    "get_variant",
    "make_tracker",
    "probe_variant",
    "variant_config",
    "variant_factory",
]

"""Multi-target tracker speed: ms per frame (median, p95) at 1, 5, 10, 20 and 50 targets in view, fused and lidar-only.

Scene (``sim.benchmarks._traffic``): a ring road of radius 500 m, lane-following cars placed so that
all of them stay in the lidar's view (the narrowest of 4, 6, 8, ... lanes on which they fit: 4 lanes up
to 20 cars, 10 lanes for 50). Per target count one sensor stream of ``--frames`` frames (default
100 = 10 s; 10 Hz lidar, 14 Hz radars, seed 0) is made once and fed to a fresh tracker of each
``--variants`` entry. Reported per variant and count: ``ms_median`` and ``ms_p95`` of ``Tracker.step``
(after a 10-frame warm-up), ``in_view_mean`` (cars with lidar points), ``tracks_mean``, ``lanes``, and
``ms_mean`` with ``stage_ms``: the mean ms per frame of each stage of ``Tracker.step``
(``Tracker.stage_seconds``, ``tracker.tracker.STAGES``), i.e. where the frame goes.

``--compare-stonesoup`` also runs Stone Soup's GM-PHD (UKF, 10 point targets, ``--stonesoup-frames``
frames, default 200) in the same process on the same frames as ours and prints the ratio of its ms per
frame to ours (``sim.benchmarks._stonesoup``); without Stone Soup it says how to install it
(``pip install -e ".[baselines]"``) and exits with status 2.

Commands::

    eot bench tracker                                  # 1 5 10 20 50 targets, fused and lidar-only
    eot bench tracker --targets 10 --variants curvilinear-fused --frames 50
    eot bench tracker --targets 10 --compare-stonesoup
    eot bench tracker --repeat 3                       # each row the fastest of 3 rounds (a shared machine)
    OMP_NUM_THREADS=1 taskset -c 0 eot bench tracker   # one core, as the issue's numbers
"""

from __future__ import annotations

import argparse
from typing import Any

from sim.benchmarks._tracking import best_of, in_view, sensor_frames, time_variant

COUNTS = (1, 5, 10, 20, 50)
VARIANTS = ("curvilinear-fused", "curvilinear-lidar")
FRAMES = 100
STONESOUP_FRAMES = 200


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--targets", type=int, nargs="+", default=list(COUNTS), help="target counts (default 1 5 10 20 50)")
    parser.add_argument("--frames", type=int, default=FRAMES, help=f"frames per count (default {FRAMES} = 10 s)")
    parser.add_argument("--variants", nargs="+", default=list(VARIANTS), help="tracker variants (default: fused and lidar-only)")
    parser.add_argument("--lanes", type=int, default=None, help="force this many lanes (default: the narrowest that fits)")
    parser.add_argument("--seed", type=int, default=0, help="scene and sensor seed (default 0)")
    parser.add_argument("--repeat", type=int, default=1,
                        help="time every count and variant this many times, in rounds, and report the fastest "
                             "round (default 1)")
    parser.add_argument("--compare-stonesoup", action="store_true",
                        help="also time Stone Soup's GM-PHD (UKF, 10 point targets) on the same frames and print the ratio")
    parser.add_argument("--stonesoup-frames", type=int, default=STONESOUP_FRAMES,
                        help=f"frames of the Stone Soup comparison (default {STONESOUP_FRAMES})")


def measure(counts: list[int] | tuple[int, ...], variants: list[str] | tuple[str, ...], frames: int, *,
            seed: int = 0, lanes: int | None = None, repeat: int = 1) -> dict[str, dict[str, dict[str, Any]]]:
    """``{variant: {str(count): row}}``: each row the ``frame_stats`` numbers plus ``lanes``. The
    tracker's kernels are compiled (or loaded) first, so no timing includes that. With ``repeat`` > 1
    every timing runs that many times, in rounds over all counts and variants (a busy minute of the
    machine then slows one round of each, not every round of one), and each row is its fastest round
    (``best_of``: with ``rounds`` and ``ms_median_rounds``)."""
    from sim.evaluation.variants import check_variant
    from tracker.warmup import warm_up

    for v in variants:
        check_variant(v)
    if isinstance(repeat, bool) or not isinstance(repeat, int) or repeat < 1:
        raise ValueError(f"repeat must be an integer >= 1; got {repeat!r}")
    warm_up()
    streams = {}
    for count in counts:
        scene, stream = sensor_frames(int(count), frames, seed=seed, lanes=lanes)
        streams[count] = (scene, stream, in_view(stream))
    rounds: dict[tuple[str, int], list[dict[str, Any]]] = {}
    for _ in range(repeat):
        for count, (scene, stream, visible) in streams.items():
            for v in variants:
                rounds.setdefault((v, count), []).append(
                    {"targets": int(count), "lanes": scene.lanes, **time_variant(v, scene, stream, visible)})
    out: dict[str, dict[str, dict[str, Any]]] = {v: {} for v in variants}
    for (key, count), rows in rounds.items():
        out[key][str(count)] = best_of(rows) if repeat > 1 else rows[0]
    return out


def run(args: argparse.Namespace) -> dict:
    compare = bool(getattr(args, "compare_stonesoup", False))
    if compare:  # before the long part: a missing Stone Soup is a usage error now
        from sim.benchmarks._stonesoup import require_stonesoup

        require_stonesoup()
    out: dict[str, Any] = {
        "scene": "ring road R 500 m, lanes 3.5 m, all cars in view (sim.benchmarks._traffic)",
        "frames": args.frames,
        "seed": args.seed,
        "repeat": args.repeat,
        "results": measure(args.targets, args.variants, args.frames, seed=args.seed, lanes=args.lanes,
                           repeat=args.repeat),
    }
    if compare:
        from sim.benchmarks._stonesoup import compare as compare_stonesoup

        out["stonesoup"] = compare_stonesoup(args.stonesoup_frames, seed=args.seed, repeat=args.repeat)
    return out


def summary(result: dict) -> str | None:
    """The Stone Soup ratio line(s), when the comparison ran (printed after the JSON)."""
    if "stonesoup" not in result:
        return None
    from sim.benchmarks._stonesoup import summary as stonesoup_summary

    return stonesoup_summary(result["stonesoup"])

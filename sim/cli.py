"""The ``eot`` command line.

Subcommands that are not built yet say so plainly and exit with status 2; nothing here prints
output that looks like results unless it computed them.
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Callable, Sequence

NOT_BUILT_EXIT = 2


def _not_built(name: str) -> Callable[[argparse.Namespace], int]:
    def run(_: argparse.Namespace) -> int:
        print(
            f"eot {name}: not built yet. This part of frenet-eot has not been implemented; "
            "see the open issues. No results were produced.",
            file=sys.stderr,
        )
        return NOT_BUILT_EXIT

    return run


def _bench(args: argparse.Namespace) -> int:
    import json

    result = args.module.run(args)
    text = json.dumps(result, indent=2)
    print(text)
    if args.json:
        with open(args.json, "w", encoding="utf-8") as fh:
            fh.write(text + "\n")
    return 0


def _scenarios(args: argparse.Namespace) -> int:
    """List the suites and the scenario files of a folder (name and one-line description)."""
    from pathlib import Path

    from sim.scenario import SCENARIO_DIR, ScenarioError, is_suite_file, load_scenario, load_suite

    folder = Path(args.dir) if args.dir else SCENARIO_DIR
    if not folder.is_dir():
        print(f"eot scenarios: no such folder {folder}", file=sys.stderr)
        return 1
    files = sorted(folder.glob("*.toml"))
    suites = [p for p in files if is_suite_file(p)]
    status = 0
    for path in suites:
        try:
            suite = load_suite(path)
        except ScenarioError as exc:
            print(f"suite {path.name}: INVALID: {exc}")
            status = 1
            continue
        members = ", ".join(p.stem for p in suite.paths)
        print(f"suite {suite.name} ({path.name}): {suite.description}\n  {members}")
    if suites:
        print()
    rows = []
    for path in files:
        if path in suites:
            continue
        try:
            spec = load_scenario(path)
            rows.append((spec.name, spec.description))
        except ScenarioError as exc:
            rows.append((path.stem, f"INVALID: {exc}"))
            status = 1
    width = max((len(name) for name, _ in rows), default=0)
    for name, description in rows:
        print(f"{name:<{width}}  {description}")
    return status


def build_parser() -> argparse.ArgumentParser:
    """The argument parser of ``eot`` with one sub-parser per subcommand."""
    parser = argparse.ArgumentParser(
        prog="eot",
        description="frenet-eot: extended object tracking in Frenet road coordinates.",
    )
    sub = parser.add_subparsers(dest="command", required=True)
    for name, help_text in [
        ("demo", "run the main demo scenario and write its results"),
        ("run", "run one scenario"),
        ("montecarlo", "Monte Carlo study over seeds"),
        ("compare", "the paper's comparison study and report"),
    ]:
        p = sub.add_parser(name, help=help_text)
        p.set_defaults(func=_not_built(name))
    p = sub.add_parser("scenarios", help="list the scenario suites and files (name and description)")
    p.add_argument("--dir", help="folder of scenario files (default: the repository's scenarios/)")
    p.set_defaults(func=_scenarios)
    from sim.benchmarks import targets

    bench = sub.add_parser("bench", help="micro-benchmarks (speed, never asserted in tests)")
    bench_sub = bench.add_subparsers(dest="target", required=True)
    for name, module in sorted(targets().items()):
        p = bench_sub.add_parser(name, help=(module.__doc__ or "").strip().splitlines()[0])
        p.add_argument("--json", help="also write the numbers to this JSON file")
        if hasattr(module, "add_arguments"):
            module.add_arguments(p)
        p.set_defaults(func=_bench, module=module)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of the ``eot`` console script; returns the process exit status."""
    parser = build_parser()
    args = parser.parse_args(argv)
    return int(args.func(args))


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())

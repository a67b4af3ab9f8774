"""Random sweep with the frame recipes of tests/test_fuzz.py, recording every failure (hypothesis stops
at the first): ``python tests/fuzz_sweep.py SEQUENCES SEED OUT.json`` (results/ROBUSTNESS.md used
1500 11). Not collected by pytest."""
import json
import sys
import warnings
from collections import Counter
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
import test_fuzz as fz  # noqa: E402
from tracker import Tracker, TrackerConfig  # noqa: E402

rng = np.random.default_rng(int(sys.argv[2]))
N = int(sys.argv[1])
choices = {
    "dt": [0.1, 0.1, 0.1, 0.0, 0.05, 1.0, 7.3, 60.0, -0.1],
    "ego": ["lane", "lane", "beside", "off", "past-end", "spin"],
    "points": [0, 1, 2, 7, 60, 400, 3000],
    "kind": ["normal", "normal", "one-spot", "origin", "duplicates", "nan-inf", "ring", "car"],
    "radar": [0, 0, 1, 5, 30],
    "radar_kind": ["near", "far", "nan-velocity", "stale"],
}
counts = Counter(); failures = []
for seq in range(N):
    road_name = ["curved", "short-segment"][rng.integers(2)]
    road = fz.ROADS[road_name]
    specs = [{k: v[rng.integers(len(v))] for k, v in choices.items()} | {"ego_s": float(rng.random()), "seed": int(rng.integers(2**31))}
             for _ in range(rng.integers(1, 7))]
    tracker = Tracker(road, TrackerConfig()); t = 0.0; last_t = None
    for i, spec in enumerate(specs):
        t += spec["dt"]
        try:
            expected = fz.expected_refusal(spec, t, last_t)
            with warnings.catch_warnings():
                warnings.simplefilter("error")
                try:
                    frame = fz.make_frame(road, t, spec)
                    tracks = tracker.step(frame)
                except ValueError as exc:
                    kind = fz.refusal_kind(exc)  # only the documented refusals, where the recipe expects them
                    assert kind == expected, f"refused as {kind!r}; the recipe expects {expected!r}: {exc}"
                    counts["refused"] += 1
                    counts["refused: " + kind] += 1
                    continue
            assert expected is None, f"stepped; the recipe expects the refusal {expected!r}"
            last_t = t
            counts["stepped"] += 1
            fz.check_tracks(tracker, tracks)
        except Exception as exc:  # noqa: BLE001
            msg = f"{type(exc).__name__}: {(str(exc).splitlines() or [''])[0][:120]}"
            counts["failed"] += 1
            failures.append({"road": road_name, "frame_index": i, "error": msg, "specs": specs[: i + 1]})
            break
json.dump({"counts": counts, "failures": failures}, open(sys.argv[3], "w"), indent=1, default=str)
print(counts.most_common(12))

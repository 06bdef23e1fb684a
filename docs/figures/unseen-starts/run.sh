#!/usr/bin/env bash
# Starts no table of docs/results.md uses ("Starts none of the tables use"): the default
# grids demonstrated on MuJoCo, the default preset's turn {angle}, approach {distance, angle}
# and turn & approach CBLM trained from them (as `behavior-hmm demo` trains them), each run
# from random starts drawn once with a fixed seed: turn 40 bearings in [-180, 180) deg at
# 0.5 m, approach 40 distances in [0.1, 1.0) m, turn & approach 60 starts, bearing in
# [-180, 180) deg and distance in [0, 1.0) m. Work files go to results/unseen-starts (or
# $1); the table is written to docs/figures/unseen-starts/table.md. 1.5 min with 2 workers
# beside a test run, measured with the MuJoCo demonstrations already in the collection cache.
set -euo pipefail
here=$(cd "$(dirname "$0")" && pwd)
work=${1:-results/unseen-starts}
workers=${BEHAVIOR_HMM_WORKERS:-2}
mkdir -p "$work"
cd "$work"
bash "$here/../default-models.sh"
python - <<'PY'
import csv

import numpy as np

rng = np.random.default_rng(20261208)


def write(name, rows):
    with open(name, "w", newline="") as f:
        out = csv.DictWriter(f, fieldnames=list(rows[0]))
        out.writeheader()
        out.writerows(rows)


write("turn_starts.csv", [{"angle": round(float(a), 1), "distance": 0.5} for a in rng.uniform(-180, 180, 40)])
write("approach_starts.csv", [{"angle": 0.0, "distance": round(float(d), 3)} for d in rng.uniform(0.1, 1.0, 40)])
angles, distances = rng.uniform(-180, 180, 60), rng.uniform(0.0, 1.0, 60)
write("ta_starts.csv", [{"angle": round(float(a), 1), "distance": round(float(d), 3)} for a, d in zip(angles, distances)])
PY
for model in turn approach ta; do
  behavior-hmm evaluate "$model.bhmm" --starts "${model}_starts.csv" --workers "$workers" \
    --json "$model.json"
done
python - "$here/table.md" <<'PY'
import json
import sys

rows = [
    "| model | starts | success % (mean) | goals | all-zero floor % | lowest three (start: success %, floor %) |",
    "| --- | --- | --- | --- | --- | --- |",
]
names = {"turn": "turn {angle}", "approach": "approach {distance, angle}", "ta": "turn & approach (CBLM)"}
for model, label in names.items():
    result = json.load(open(f"{model}.json"))
    cases = result["cases"]
    low = sorted(cases, key=lambda c: c["success_rate"])[:3]
    worst = "; ".join(
        f"{c['start'].get('angle', 0):.1f} deg, {c['start'].get('distance', 0):.3f} m: "
        f"{c['success_rate']:.1f}, {c['zero_floor']:.1f}"
        for c in low
    )
    rows.append(
        f"| {label} | {len(cases)} | {result['success_rate_mean']:.2f} | "
        f"{result['goal_reached']}/{len(cases)} | {result['zero_floor_mean']:.1f} | {worst} |"
    )
    if model == "ta":
        near = [c for c in cases if c["start"]["distance"] < 0.1]
        mean = sum(c["success_rate"] for c in near) / len(near)
        floor = sum(c["zero_floor"] for c in near) / len(near)
        goals = sum(bool(c["goal_reached"]) for c in near)
        rows.append(
            f"| turn & approach, the starts closer than 0.1 m (the nearest demonstrated approach start) "
            f"| {len(near)} | {mean:.2f} | {goals}/{len(near)} | {floor:.1f} | |"
        )
open(sys.argv[1], "w").write("\n".join(rows) + "\n")
print("\n".join(rows))
PY

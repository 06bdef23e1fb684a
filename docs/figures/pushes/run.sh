#!/usr/bin/env bash
# Pushes of docs/results.md ("Performing like the teacher"): the default grids demonstrated
# on MuJoCo, the default preset's turn {angle}, approach {distance, angle} and turn & approach
# CBLM trained from them, every model pushed 20 deg of bearing and 0.05 m of distance at half
# the teacher's duration, seeds 0, 1, 2 (45 runs per row). Work files go to results/pushes
# (or $1); the table is written to docs/figures/pushes/table.md. 3.6 min with 2 workers, measured
# with the MuJoCo demonstrations already in the collection cache.
set -euo pipefail
here=$(cd "$(dirname "$0")" && pwd)
work=${1:-results/pushes}
workers=${BEHAVIOR_HMM_WORKERS:-2}
mkdir -p "$work"
cd "$work"
bash "$here/../default-models.sh"
for model in turn approach ta; do
  for seed in 0 1 2; do
    behavior-hmm evaluate "$model.bhmm" --push at=0.5,angle=20 --seed "$seed" \
      --workers "$workers" --json "$model-angle-$seed.json"
    behavior-hmm evaluate "$model.bhmm" --push at=0.5,distance=0.05 --seed "$seed" \
      --workers "$workers" --json "$model-distance-$seed.json"
  done
done
python - "$here/table.md" <<'PY'
import json
import sys

names = {"turn": "turn {angle}", "approach": "approach {distance, angle}",
         "ta": "turn & approach (CBLM)"}
rows = ["| model | 20° of bearing at half the teacher's duration: goals, success % "
        "| 0.05 m of distance: goals, success % |", "| --- | --- | --- |"]
for model, label in names.items():
    cells = []
    for push in ("angle", "distance"):
        runs = [json.load(open(f"{model}-{push}-{s}.json")) for s in (0, 1, 2)]
        goals = sum(int(r["goal_reached"]) for r in runs)
        n = sum(int(r["n"]) for r in runs)
        rates = [c["success_rate"] for r in runs for c in r["cases"]]
        cells.append(f"{goals}/{n}, {sum(rates) / len(rates):.1f}")
    rows.append(f"| {label} | {cells[0]} | {cells[1]} |")
text = ("Pushes, MuJoCo, default preset, seeds 0-2 (45 runs per cell; "
        "`bash docs/figures/pushes/run.sh`).\n\n" + "\n".join(rows) + "\n")
open(sys.argv[1], "w").write(text)
print(text)
PY

#!/bin/bash
# An SBLM grown by `train simple --update` on half of a default grid, against a fit on
# all of it (docs/results.md, "An SBLM grown by new demonstrations of its own behavior").
# Run from the repository root: bash docs/figures/incremental-split/run.sh [WORK_FOLDER]
set -euo pipefail
S=docs/figures/incremental-split
W=${1:-results/incremental-split}
mkdir -p "$W"
: > "$W/log.txt"
for task in turn approach; do
  if [ $task = turn ]; then inputs=angle; corr=0; else inputs=distance,angle; corr=1; fi
  for k in 0 1 2; do
    P=$W/$task-$k
    mkdir -p "$P"
    for part in A B AB; do
      behavior-hmm -q collect $task --sim kinematic --starts $S/$task-split$k-$part.csv \
        --corrections $corr -o "$P/$part.parquet" >> "$W/log.txt"
    done
    behavior-hmm -q train simple "$P/A.parquet" --inputs $inputs -o "$P/a.bhmm" >> "$W/log.txt"
    behavior-hmm -q train simple "$P/B.parquet" --update "$P/a.bhmm" -o "$P/ab.bhmm" >> "$W/log.txt"
    behavior-hmm -q train simple "$P/AB.parquet" --inputs $inputs -o "$P/full.bhmm" >> "$W/log.txt"
    for m in a ab full; do
      behavior-hmm -q evaluate "$P/$m.bhmm" --sim kinematic --json "$P/$m-test.json" > /dev/null
      for part in A B; do
        behavior-hmm -q evaluate "$P/$m.bhmm" --sim kinematic --starts $S/$task-split$k-$part.csv \
          --json "$P/$m-$part.json" > /dev/null
      done
    done
  done
done
python3 - "$W" "$S" <<'PY' | tee "$W/table.md"
import json, re, sys
W, S = sys.argv[1], sys.argv[2]
times = {}
for line in open(f"{W}/log.txt"):
    m = re.search(r"/(\w+)-(\d)/(\w+)\.bhmm.*?\((\d+\.\d) s\)", line)
    if m:
        times[m.group(1, 2, 3)] = float(m.group(4))
print("| task | split | A + B | A alone: old starts · test | grown by B (`--update`): old · new · test"
      " | fit on A + B: old · new · test | update s / refit s |")
print("| --- | --- | --- | --- | --- | --- | --- |")
for t in ("turn", "approach"):
    for k in "012":
        def cell(m, w):
            d = json.load(open(f"{W}/{t}-{k}/{m}-{w}.json"))
            return f"{d['success_rate_mean']:.1f} ({d['goal_reached']}/{d['n']})"
        n = [sum(1 for _ in open(f"{S}/{t}-split{k}-{p}.csv")) - 1 for p in "AB"]
        print(f"| {t} | {k} | {n[0]} + {n[1]} | {cell('a', 'A')} · {cell('a', 'test')} | "
              f"{cell('ab', 'A')} · {cell('ab', 'B')} · {cell('ab', 'test')} | "
              f"{cell('full', 'A')} · {cell('full', 'B')} · {cell('full', 'test')} | "
              f"{times[(t, k, 'ab')]:.1f} / {times[(t, k, 'full')]:.1f} |")
PY

"""``python -m behavior_hmm.benchmarks NAME [--json OUT.json] [--quick]``."""

from __future__ import annotations

import argparse
import json
import sys

from behavior_hmm.benchmarks import available, run_benchmark


def main() -> int:
    parser = argparse.ArgumentParser(prog="python -m behavior_hmm.benchmarks", description=__doc__)
    parser.add_argument("name", choices=available())
    parser.add_argument("--json", dest="json_out")
    parser.add_argument("--quick", action="store_true")
    args = parser.parse_args()
    results = run_benchmark(args.name, quick=args.quick)
    text = json.dumps(results, indent=2, sort_keys=True)
    print(text)
    if args.json_out:
        with open(args.json_out, "w", encoding="utf-8") as fh:
            fh.write(text + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())

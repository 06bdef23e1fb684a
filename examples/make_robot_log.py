"""Write examples/robot_log.csv: teacher demonstrations dressed up as a foreign robot's log.

Three turns in place recorded on the kinematic simulator, then renamed and converted the way
another robot's logger might write them: named runs, time in milliseconds, the bearing in
radians, the range in centimetres, wheel speeds in rpm and no velocity columns. import-csv
turns it back into a dataset (examples/README.md has the command). Run from the repository
root: python examples/make_robot_log.py
"""

from __future__ import annotations

import csv
import math
from pathlib import Path

from behavior_hmm.teach import collect

STARTS = [{"angle": 150.0}, {"angle": -100.0}, {"angle": 60.0}]
RUNS = ["run-a", "run-b", "run-c"]
HEADER = ["run", "time_ms", "bearing_rad", "range_cm", "wheel_l_rpm", "wheel_r_rpm"]
RAD_S_TO_RPM = 60.0 / (2.0 * math.pi)


def fixed(value: float, digits: int) -> str:
    """``value`` with ``digits`` decimals, never "-0.00"."""
    text = f"{value:.{digits}f}"
    return text[1:] if text.startswith("-") and float(text) == 0.0 else text


def main() -> None:
    demos = collect("turn", STARTS, sim="kinematic", seed=7)
    out = Path(__file__).with_name("robot_log.csv")
    with out.open("w", newline="", encoding="utf-8") as fh:
        writer = csv.writer(fh, lineterminator="\n")
        writer.writerow(HEADER)
        for run, episode in zip(RUNS, demos.episodes(), strict=True):
            t, angle, distance, left, right = episode.columns(
                ["t", "angle", "distance", "left", "right"]
            ).T
            for row in zip(t, angle, distance, left, right, strict=True):
                writer.writerow(
                    [
                        run,
                        round(row[0] * 1000.0),
                        fixed(math.radians(row[1]), 5),
                        fixed(row[2] * 100.0, 2),
                        fixed(row[3] * RAD_S_TO_RPM, 2),
                        fixed(row[4] * RAD_S_TO_RPM, 2),
                    ]
                )
    print(f"wrote {out}")


if __name__ == "__main__":
    main()

"""Plots of the scaling curves for docs/performance.md, from the benchmarks' JSON.

Usage::

    python -m behavior_hmm.benchmarks._plot --step step.json --train train.json \
        --hmm hmm.json --memory memory.json -o DIR

Writes ``step_scaling.png`` (control step against observation categories and against
primitives), ``train_curve.png`` (training time against demonstrations),
``viterbi.png`` (ours against hmmlearn) and ``memory_scaling.png`` (the sparse
Behavior-HMM's load and per-cycle planning against observation categories), for the
files given.
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path
from typing import Any


def _load(path: str | None) -> dict[str, Any] | None:
    return None if path is None else json.loads(Path(path).read_text(encoding="utf-8"))


def _save(fig: Any, path: Path) -> Path:
    """Lay ``fig`` out, write it to ``path`` (110 dpi) and close it."""
    import matplotlib.pyplot as plt

    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


def _log_log(ax: Any, xlabel: str, title: str) -> None:
    """Both axes logarithmic, a label, a title and the grid of the scaling figures."""
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.set_xlabel(xlabel)
    ax.set_title(title, fontsize=10)
    ax.grid(True, which="both", alpha=0.3)


def plot_step(results: dict[str, Any], out: Path) -> Path:
    import matplotlib.pyplot as plt

    rows = results["scaling"]
    fig, axes = plt.subplots(1, 2, figsize=(10, 3.8), sharey=True)
    for ax, varied, key, label in (
        (axes[0], "observations", "observation_categories", "observation categories"),
        (axes[1], "primitives", "primitives", "primitives (motion generators)"),
    ):
        sel = sorted((r for r in rows if r["varied"] == varied), key=lambda r: r[key])
        base = {"observation_categories": results["observation_categories"]}
        base["primitives"] = results["primitives"]
        if varied == "primitives":  # the default model is the curve's first point
            sel = [
                {
                    "primitives": results["primitives"],
                    "step_us_median": results["step_us_median"],
                    "step_us_p99": results["step_us_p99"],
                },
                *sel,
            ]
        x = [r[key] for r in sel]
        ax.plot(x, [r["step_us_median"] for r in sel], "o-", label="median")
        ax.plot(x, [r["step_us_p99"] for r in sel], "s--", label="99th percentile")
        other = "primitives" if varied == "observations" else "observation categories"
        fixed = base["primitives"] if varied == "observations" else base["observation_categories"]
        _log_log(ax, label, f"{label}; {other} ≈ {fixed}")
    axes[0].set_ylabel("control step, µs (wall clock)")
    axes[0].axhline(1000, color="red", lw=0.8, ls=":")
    axes[0].text(120, 1080, "1 ms: p99 target at 5,000 categories", color="red", fontsize=8)
    axes[1].legend(loc="upper left")
    fig.suptitle("SBLM control step (turn, kinematic robot, 15 test starts)", fontsize=11)
    return _save(fig, out / "step_scaling.png")


def plot_train(results: dict[str, Any], out: Path) -> Path:
    import matplotlib.pyplot as plt

    rows = results["demonstrations_curve"]
    fig, ax = plt.subplots(figsize=(5.5, 3.8))
    x = [r["demonstrations"] for r in rows]
    ax.plot(x, [r["train_s"] for r in rows], "o-")
    for r in rows:
        ax.annotate(
            f"×{r['grid_factor']}, {r['samples'] // 1000}k rows",
            (r["demonstrations"], r["train_s"]),
            textcoords="offset points",
            xytext=(4, -12),
            fontsize=8,
        )
    ax.set_xlabel("demonstrations (turn, kinematic)")
    ax.set_ylabel("training time of the SBLM, s")
    ax.set_xlim(0, max(x) * 1.15)
    ax.set_ylim(0, max(r["train_s"] for r in rows) * 1.15)
    ax.grid(True, alpha=0.3)
    ax.set_title("Training time against demonstrations", fontsize=11)
    return _save(fig, out / "train_curve.png")


def plot_hmm(results: dict[str, Any], out: Path) -> Path:
    import matplotlib.pyplot as plt

    rows = results["sizes"]
    fig, ax = plt.subplots(figsize=(5.5, 3.8))
    labels = [f"{r['states']} × {r['steps']}" for r in rows]
    kernel = results.get("kernel", "numpy")  # files written before the numba kernel: numpy
    bars = [(f"ours (BehaviorHMM.viterbi, {kernel})", "ours_us_median")]
    if any(r.get("ours_numpy_us_median") for r in rows):  # numba ran: numpy timed beside it
        bars.append(("ours (numpy kernel)", "ours_numpy_us_median"))
    bars.append(("hmmlearn (decode, viterbi)", "hmmlearn_us_median"))
    width = 0.8 / len(bars)
    xs = range(len(rows))
    for k, (label, key) in enumerate(bars):
        shift = (k - (len(bars) - 1) / 2) * width
        values = [(r.get(key) or 0) / 1000 for r in rows]
        ax.bar([x + shift for x in xs], values, width, label=label)
    ax.set_xticks(list(xs), labels)
    ax.set_yscale("log")
    ax.set_xlabel("states × steps")
    ax.set_ylabel("median, ms")
    ax.legend()
    ax.set_title("Viterbi on the same models", fontsize=11)
    return _save(fig, out / "viterbi.png")


def plot_memory(results: dict[str, Any], out: Path) -> Path:
    import matplotlib.pyplot as plt

    rows = sorted(results["scaling"], key=lambda r: (r["observation_categories"], r["states"]))
    x = [r["observation_categories"] for r in rows]
    fig, axes = plt.subplots(1, 3, figsize=(14, 3.8))
    axes[0].plot(x, [r["load_s"] * 1e3 for r in rows], "o-", label="load")
    axes[1].plot(x, [r["load_peak_above_imports_mb"] for r in rows], "o-", label="load peak")
    axes[1].plot(x, [r["dense_c_would_be_mb"] for r in rows], "k:", label="one dense C table")
    axes[2].plot(x, [r["step_us_p99"] for r in rows], "o-", label="HMM calls, 99th pct.")
    axes[2].plot(
        x, [r["step_us_median"] for r in rows], "s-", color="green", label="HMM calls, median"
    )
    control = [r for r in rows if "control_step_us_p99" in r]
    if control:  # runs that also categorized a reading every cycle
        cx = [r["observation_categories"] for r in control]
        for key, style, color, what in (
            ("median", "s-", "orchid", "median"),
            ("p99", "o-", "purple", "99th pct."),
            ("max", "^--", "grey", "maximum"),
        ):
            axes[2].plot(
                cx,
                [r[f"control_step_us_{key}"] for r in control],
                style,
                color=color,
                label=f"categorization + HMM, {what}",
            )
    else:
        axes[2].plot(x, [r["step_us_max"] for r in rows], "^--", color="grey", label="maximum")
    axes[2].axhline(1000, color="red", lw=0.8, ls=":", label="1 ms")
    titles = ("load of the file, ms", "load peak above imports, MB", "per control cycle, µs")
    for ax, title in zip(axes, titles, strict=True):
        first = ax.lines[0].get_ydata()  # name each point of the first curve by its states
        for i, r in enumerate(rows):
            ax.annotate(
                f"N={r['states']:,}",
                (x[i], first[i]),
                textcoords="offset points",
                xytext=(4, -10 if i % 2 else 4),
                fontsize=7,
            )
        _log_log(ax, "observation categories", title)
        if ax is axes[2]:
            ax.legend(fontsize=7, loc="upper left", bbox_to_anchor=(1.02, 1.0))
        else:
            ax.legend(fontsize=7, loc="upper left")
    fig.suptitle("Sparse Behavior-HMM on synthetic models (bench memory; N = states)", fontsize=11)
    return _save(fig, out / "memory_scaling.png")


def main() -> int:
    parser = argparse.ArgumentParser(
        prog="python -m behavior_hmm.benchmarks._plot", description=__doc__
    )
    parser.add_argument("--step")
    parser.add_argument("--train")
    parser.add_argument("--hmm")
    parser.add_argument("--memory")
    parser.add_argument("-o", "--out", required=True)
    args = parser.parse_args()
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    plots = (
        (args.step, plot_step),
        (args.train, plot_train),
        (args.hmm, plot_hmm),
        (args.memory, plot_memory),
    )
    for path, plot in plots:
        data = _load(path)
        if data is not None:
            print(plot(data, out))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())

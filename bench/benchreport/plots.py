"""The report's three figures (matplotlib, headless Agg backend), from the CSV's rows.

  error_vs_spp     error against samples per pixel, one curve per chain, log-log: the layout of
                   the progressive-denoising paper's Fig. 11 (a scene per panel; the generated
                   set as the mean over its crops)
  pareto           error against time (x the in-run baseline): each chain's mean over a group,
                   the chains no other chain beats on both joined (the Pareto front)
  time_vs_pixels   stage wall time, process CPU time and peak memory against pixel count,
                   one line per chain (CPU time is what survives a busy machine)
"""
import math
from collections import defaultdict

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402  (after choosing the backend)
import matplotlib.ticker  # noqa: E402

from .runs import CHAINS  # noqa: E402
from .summary import chain_order, group_title, ok_rows  # noqa: E402

CHAIN_NAMES = [c.name for c in CHAINS]

DPI = 80


def colour(chain, chains=None):
    """The same colour for a chain in every figure (its place in runs.CHAINS)."""
    return plt.get_cmap("tab10")(CHAIN_NAMES.index(chain) % 10)


def mean(values):
    values = list(values)
    return sum(values) / len(values) if values else float("nan")


def spp_panels(rows):
    """(title, {chain: [(spp, error)]}) per panel: every scene with several spp levels outside
    the generated set, then the generated set's mean per spp over its crops."""
    panels = []
    by_scene = defaultdict(list)
    for row in rows:
        if row["group"] not in ("generated", "scaling"):
            by_scene[(row["group"], row["scene"])].append(row)
    multi = {k: v for k, v in by_scene.items() if len({r["spp"] for r in v}) > 1}
    for (group, scene), scene_rows in sorted((multi or by_scene).items()):
        curves = defaultdict(list)
        for row in scene_rows:
            curves[row["chain"]].append((row["spp"], row["relmse"]))
        panels.append((f"{scene} ({group})", curves))
    generated = [r for r in rows if r["group"] == "generated"]
    if generated:
        per = defaultdict(list)
        for row in generated:
            per[(row["chain"], row["spp"])].append(row["relmse"])
        curves = defaultdict(list)
        for (chain, spp), errors in per.items():
            curves[chain].append((spp, mean(errors)))
        crops = len({r["scene"] for r in generated})
        panels.append((f"generated set, mean of {crops} crops", curves))
    return panels


def error_vs_spp(rows, path):
    rows = ok_rows(rows)
    chains = chain_order(rows)
    panels = spp_panels(rows)[:4]
    figure, axes = plt.subplots(1, max(1, len(panels)), figsize=(4.2 * max(1, len(panels)), 3.4),
                                squeeze=False)
    for ax, (title, curves) in zip(axes[0], panels):
        for chain in chains:
            points = sorted(curves.get(chain, []))
            if points:
                ax.plot([p[0] for p in points], [p[1] for p in points], marker="o", ms=3, lw=1.2,
                        color=colour(chain, chains), label=chain,
                        ls="--" if chain == "noisy" else "-")
        ax.set_xscale("log", base=2)
        ax.set_yscale("log")
        ax.set_xlabel("samples per pixel")
        ax.set_ylabel("relMSE")
        ax.set_title(title, fontsize=9)
        ax.grid(True, which="both", alpha=0.3)
    axes[0][-1].legend(fontsize=7, loc="best")
    figure.tight_layout()
    figure.savefig(path, dpi=DPI)
    plt.close(figure)


def pareto_front(points):
    """The (x, y, label) points no other point beats on both x and y, by increasing x."""
    front, best_y = [], math.inf
    for x, y, label in sorted(points):
        if y < best_y:
            front.append((x, y, label))
            best_y = y
    return front


def pareto(rows, path):
    rows = ok_rows(rows)
    chains = chain_order(rows)
    groups = [g for g in ("shared", "generated", "caustics", "custom")
              if any(r["group"] == g for r in rows)]
    figure, axes = plt.subplots(1, max(1, len(groups)), figsize=(4.6 * max(1, len(groups)), 3.6),
                                squeeze=False)
    for ax, group in zip(axes[0], groups):
        group_rows = [r for r in rows if r["group"] == group]
        points = []
        for chain in chains:
            mine = [r for r in group_rows if r["chain"] == chain]
            if chain == "noisy":
                ax.axhline(mean(r["relmse"] for r in mine), color="grey", ls="--", lw=1,
                           label="noisy input")
                continue
            x = [r["stage_x_baseline"] for r in mine]
            y = [r["relmse"] for r in mine]
            ax.scatter(x, y, s=6, alpha=0.25, color=colour(chain, chains))
            points.append((mean(x), mean(y), chain))
            ax.scatter([mean(x)], [mean(y)], s=40, color=colour(chain, chains), label=chain,
                       edgecolor="black", lw=0.5, zorder=3)
        front = pareto_front(points)
        ax.plot([p[0] for p in front], [p[1] for p in front], "k-", lw=1, zorder=2,
                label="Pareto front")
        ax.set_xscale("log")
        ax.set_yscale("log")
        ax.xaxis.set_minor_formatter(matplotlib.ticker.NullFormatter())  # labels collide
        ax.set_xlabel("stage time / baseline op (same run)")
        ax.set_ylabel("relMSE")
        n = len({(r["scene"], r["spp"]) for r in group_rows})
        ax.set_title(f"{group_title(group)}: mean of {n} renders (dots: each)", fontsize=9)
        ax.grid(True, which="both", alpha=0.3)
    axes[0][-1].legend(fontsize=7, loc="best")
    figure.tight_layout()
    figure.savefig(path, dpi=DPI)
    plt.close(figure)


def time_vs_pixels(rows, path):
    rows = [r for r in ok_rows(rows) if r["chain"] != "noisy"]
    chains = chain_order(rows)
    figure, axes = plt.subplots(1, 3, figsize=(12, 3.4))
    for ax, key, label in ((axes[0], "stage_s", "stage wall time (s)"),
                           (axes[1], "cpu_s", "process CPU time (s)"),
                           (axes[2], "peak_rss_mb", "peak RSS of the process (MB)")):
        for chain in chains:
            per = defaultdict(list)
            for row in rows:
                if row["chain"] == chain:
                    per[row["pixels"]].append(row[key])
            points = sorted((pixels, mean(values)) for pixels, values in per.items())
            ax.plot([p[0] for p in points], [p[1] for p in points], "o-", ms=3, lw=1.2,
                    color=colour(chain, chains), label=chain)
        ax.set_xscale("log")
        ax.set_yscale("log")
        ax.set_xlabel("pixels")
        ax.set_ylabel(label)
        ax.grid(True, which="both", alpha=0.3)
    axes[0].set_title("denoising stages, wall (mean per size)", fontsize=9)
    axes[1].set_title("whole mcdntool run, user+system CPU", fontsize=9)
    axes[2].set_title("memory (mean per size)", fontsize=9)
    axes[0].legend(fontsize=7, loc="best")
    figure.tight_layout()
    figure.savefig(path, dpi=DPI)
    plt.close(figure)


def colour_scale(path, cmap, low, high, label):
    """A horizontal colour bar: the key to the heatmaps (inferno) or alpha' maps (viridis)."""
    figure, ax = plt.subplots(figsize=(3.2, 0.75))
    figure.colorbar(matplotlib.cm.ScalarMappable(matplotlib.colors.Normalize(low, high), cmap),
                    cax=ax, orientation="horizontal", label=label)
    figure.tight_layout()
    figure.savefig(path, dpi=DPI)
    plt.close(figure)

"""The headline tables, from the CSV's rows: error per render and chain, time and memory per
chain and image size. Shared by the HTML report and summary.md (the README's tables)."""
from collections import defaultdict

from .runs import CHAINS

GROUP_TITLES = {"shared": "../shared/data", "generated": "generated set", "caustics": "caustics crops",
                "custom": "given scenes", "scaling": "box cut/tiled to sizes"}


def group_title(group):
    return GROUP_TITLES.get(group, group)


def ok_rows(rows):
    return [r for r in rows if r["status"] == "ok"]


def chain_order(rows):
    present = {r["chain"] for r in rows}
    return [c.name for c in CHAINS if c.name in present]


def mean(values):
    values = list(values)
    return sum(values) / len(values) if values else None


def error_table(rows, metric="relmse"):
    """(header, body, best): a line per render of the shared and given scenes and of the
    caustics crops, and a line per spp of the generated set (mean over its crops); a column
    per chain; best[i] is the column of line i's smallest error (SSIM: largest), denoisers
    only."""
    rows = ok_rows(rows)
    chains = chain_order(rows)
    lines = []
    seen = []
    for row in rows:
        key = (row["group"], row["scene"], row["spp"])
        if row["group"] in ("shared", "custom", "caustics") and key not in seen:
            seen.append(key)
    for group, scene, spp in seen:
        values = {r["chain"]: r[metric] for r in rows
                  if (r["group"], r["scene"], r["spp"]) == (group, scene, spp)}
        lines.append((f"{scene} {spp} spp", values))
    per = defaultdict(list)
    crops = defaultdict(set)
    for row in rows:
        if row["group"] == "generated":
            per[(row["spp"], row["chain"])].append(row[metric])
            crops[row["spp"]].add(row["scene"])
    for spp in sorted(crops):
        values = {chain: mean(per[(spp, chain)]) for chain in chains if per[(spp, chain)]}
        lines.append((f"generated {spp} spp (mean of {len(crops[spp])})", values))
    header = ["render"] + chains
    body, best = [], []
    pick = max if metric in ("ssim", "psnr") else min
    for label, values in lines:
        body.append([label] + [values.get(c) for c in chains])
        denoisers = [c for c in chains if c != "noisy" and values.get(c) is not None]
        best.append(1 + chains.index(pick(denoisers, key=lambda c: values[c])) if denoisers else None)
    return header, body, best


def speed_table(rows):
    """(header, body): a line per chain; a column per image size: mean stage wall time in
    seconds, its ratio to the baseline op, the process's CPU seconds (reading and writing
    included) and its mean peak RSS."""
    rows = ok_rows(rows)
    chains = chain_order(rows)
    sizes = sorted({(r["width"], r["height"]) for r in rows}, key=lambda s: s[0] * s[1])
    header = ["chain"] + [f"{w}x{h}" for w, h in sizes]
    body = []
    for chain in chains:
        line = [chain]
        for size in sizes:
            mine = [r for r in rows if r["chain"] == chain and (r["width"], r["height"]) == size]
            if not mine:
                line.append("")
                continue
            line.append(f"{mean(r['stage_s'] for r in mine):.2f} s "
                        f"({mean(r['stage_x_baseline'] for r in mine):.0f}x), "
                        f"{mean(r['cpu_s'] for r in mine):.1f} CPU s, "
                        f"{mean(r['peak_rss_mb'] for r in mine):.0f} MB")
        body.append(line)
    return header, body


def cell(value):
    if value is None:
        return ""
    if isinstance(value, float):
        return f"{value:.3g}" if abs(value) < 1e-3 else f"{value:.4f}"
    return str(value)


def measured_on(meta):
    """The line saying when, on what and from which commit the tables were measured."""
    parts = [meta.get("date", "date unknown"), meta.get("machine", "machine unknown")]
    if "threads per run" in meta:
        parts.append(f"{meta['threads per run']} threads per run")
    if "commit" in meta:
        parts.append(f"commit {meta['commit']}")
    return "Measured " + ", ".join(str(p) for p in parts) + " (bench/report).\n"


def markdown(rows, baseline_note, meta=None):
    """summary.md: both tables as GitHub markdown (the best denoiser of a line in bold), after
    a line saying where they were measured (meta.json's date, machine, threads, commit)."""
    out = [measured_on(meta or {})]
    for title, metric in (("relMSE", "relmse"), ("SSIM", "ssim")):
        header, body, best = error_table(rows, metric)
        out.append(f"{title} (best denoiser of each line in bold)\n")
        out.append("| " + " | ".join(header) + " |")
        out.append("|---" + "|---:" * (len(header) - 1) + "|")
        for line, b in zip(body, best):
            cells = [cell(v) for v in line]
            if b is not None:
                cells[b] = f"**{cells[b]}**"
            out.append("| " + " | ".join(cells) + " |")
        out.append("")
    header, body = speed_table(rows)
    out.append(f"Stage wall time (x {baseline_note}), process CPU time and peak RSS, "
               "mean per image size\n")
    out.append("| " + " | ".join(header) + " |")
    out.append("|---" + "|---:" * (len(header) - 1) + "|")
    for line in body:
        out.append("| " + " | ".join(line) + " |")
    return "\n".join(out) + "\n"

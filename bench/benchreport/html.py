"""report.html: the tables, the plots, and per render the reference, each chain's result, its
relMSE heatmap and the mixes' alpha' maps. Offline: every link is relative, nothing is fetched.

A small script at the end checks, once the page has loaded, that every <img> decoded
(naturalWidth > 0) and writes the counts into #load-check; the headless-Chromium test reads
them (tests/bench/test_report.py), a reader sees the same line.
"""
import html
import os

from .runs import CHAINS
from .summary import cell, chain_order, error_table, group_title, speed_table

STYLE = """
body { font: 14px/1.4 sans-serif; margin: 1.5em; color: #222; max-width: 1400px; }
table { border-collapse: collapse; margin: 0.5em 0 1.5em; font-size: 12px; }
th, td { border: 1px solid #ccc; padding: 2px 6px; text-align: right; }
th:first-child, td:first-child { text-align: left; }
td.best { font-weight: bold; background: #e8f4e8; }
td.failed { color: #a00; text-align: left; }
.plots img { max-width: 100%; margin: 0.3em 0; display: block; }
.render { display: flex; flex-wrap: wrap; gap: 8px; align-items: flex-start; }
.chain { border: 1px solid #ddd; padding: 4px; }
.chain img { width: 160px; image-rendering: pixelated; display: block; margin-bottom: 2px; }
figure { margin: 0; } figcaption { font-size: 11px; max-width: 330px; }
#load-check { font-size: 12px; color: #555; }
"""

LOAD_CHECK = """
<script>
window.addEventListener('load', function () {
  var images = Array.prototype.slice.call(document.images);
  var broken = images.filter(function (i) { return !(i.complete && i.naturalWidth > 0); });
  var check = document.getElementById('load-check');
  check.dataset.images = images.length;
  check.dataset.broken = broken.length;
  check.dataset.tables = document.querySelectorAll('table').length;
  check.textContent = 'Page check: ' + images.length + ' images, ' + broken.length +
    ' not loaded' + (broken.length ? ' (' + broken.map(function (i) {
      return i.getAttribute('src'); }).join(', ') + ')' : '') + '; ' +
    check.dataset.tables + ' tables.';
});
</script>
"""

RUN_COLUMNS = ["group", "scene", "spp", "width", "height", "chain", "wall_s", "stage_s",
               "stage_x_baseline", "cpu_s", "peak_rss_mb", "relmse", "rmse", "smape", "ssim",
               "alpha_mean", "status"]


def esc(value):
    return html.escape(str(value), quote=True)


def table(table_id, header, body, best=None, failed_column=None):
    out = [f'<table id="{table_id}"><tr>' + "".join(f"<th>{esc(h)}</th>" for h in header) + "</tr>"]
    for i, line in enumerate(body):
        cells = []
        for j, value in enumerate(line):
            css = ""
            if best and best[i] == j:
                css = ' class="best"'
            elif failed_column == j and value not in ("ok", ""):
                css = ' class="failed"'
            cells.append(f"<td{css}>{esc(cell(value))}</td>")
        out.append("<tr>" + "".join(cells) + "</tr>")
    return "\n".join(out + ["</table>"])


def image(out_dir, path, alt):
    """An <img> with a relative link, or '' if the picture was not written."""
    if not os.path.exists(os.path.join(out_dir, path)):
        return ""
    return f'<img src="{esc(path)}" alt="{esc(alt)}">'


def render_sections(out_dir, rows):
    """Per render (not the scaling copies): the reference, then per chain its result, relMSE
    heatmap and (mixes) alpha' map, captioned with the numbers."""
    sections = []
    chains = chain_order(rows)
    keys = []
    for row in rows:
        key = (row["group"], row["scene"], row["spp"])
        if row["group"] != "scaling" and key not in keys:
            keys.append(key)
    for group, scene, spp in keys:
        folder = f"images/{scene}_{spp:04d}spp"
        mine = {r["chain"]: r for r in rows if (r["group"], r["scene"], r["spp"]) == (group, scene, spp)}
        figures = [f'<figure class="chain">{image(out_dir, folder + "/reference.png", "reference")}'
                   f"<figcaption>reference</figcaption></figure>"]
        for chain in (c for c in CHAINS if c.name in chains and c.name in mine):
            row = mine[chain.name]
            pictures = [image(out_dir, f"{folder}/{chain.file_name}.png", f"{chain.name} result"),
                        image(out_dir, f"{folder}/{chain.file_name}_relmse.png", f"{chain.name} relMSE heatmap")]
            if chain.mixes:
                pictures.append(image(out_dir, f"{folder}/{chain.file_name}_alpha.png", f"{chain.name} alpha'"))
            if row["status"] == "ok":
                caption = (f"<b>{esc(chain.name)}</b>: relMSE {cell(row['relmse'])}, SSIM "
                           f"{cell(row['ssim'])}, {row['stage_s']:.2f} s")
                if chain.mixes:
                    caption += f", mean alpha' {row['alpha_mean']:.3f}"
                caption += "<br>result, relMSE heatmap" + (", alpha' map" if chain.mixes else "")
            else:
                caption = f"<b>{esc(chain.name)}</b>: {esc(row['status'])}"
            figures.append(f'<figure class="chain"><div class="render">{"".join(pictures)}</div>'
                           f"<figcaption>{caption}</figcaption></figure>")
        sections.append(f"<h3>{esc(scene)}, {spp} spp ({esc(group_title(group))})</h3>\n"
                        f'<div class="render">{"".join(figures)}</div>')
    return "\n".join(sections)


def write_report(out_dir, rows, meta, plots):
    """Writes out_dir/report.html; `plots` are paths relative to out_dir."""
    error_header, error_body, error_best = error_table(rows, "relmse")
    ssim_header, ssim_body, ssim_best = error_table(rows, "ssim")
    speed_header, speed_body = speed_table(rows)
    runs_body = [[row.get(c, "") for c in RUN_COLUMNS] for row in rows]
    meta_lines = "".join(f"<li>{esc(k)}: {esc(v)}</li>" for k, v in meta.items())
    plot_images = "".join(image(out_dir, p, os.path.basename(p)) for p in plots)
    page = f"""<!doctype html>
<html lang="en"><head><meta charset="utf-8"><title>mcdenoise benchmark report</title>
<style>{STYLE}</style></head><body>
<h1>mcdenoise benchmark report</h1>
<ul>{meta_lines}</ul>
<p id="load-check">Page check: not run (JavaScript off).</p>
<h2>Error against the reference</h2>
<p>relMSE (lower is better; the best denoiser of each line is highlighted). The generated
lines are means over the set's crops. All numbers: <a href="results.csv">results.csv</a>.</p>
{table("error-relmse", error_header, error_body, error_best)}
<p>SSIM (higher is better).</p>
{table("error-ssim", ssim_header, ssim_body, ssim_best)}
<h2>Time and memory</h2>
<p>Stage time: the wall time of the denoising stages alone (mcdntool -v), mean per image size;
in brackets as a multiple of the baseline op timed just before each run; then the user+system
CPU time of the whole mcdntool process (reading and writing included) and its peak RSS.</p>
{table("speed", speed_header, speed_body)}
<h2>Plots</h2>
<div class="plots">{plot_images}</div>
<h2>Images</h2>
<p>Per render: the result (clamped, gamma 2.2), its per-pixel relMSE (log10, left scale) and
for the mixes the final alpha' (0: the render, 1: the denoised image; right scale).</p>
<div class="render">{image(out_dir, "plots/heatmap_scale.png", "heatmap colour scale")}
{image(out_dir, "plots/alpha_scale.png", "alpha colour scale")}</div>
{render_sections(out_dir, rows)}
<h2>Every run</h2>
{table("runs", RUN_COLUMNS, runs_body, failed_column=len(RUN_COLUMNS) - 1)}
{LOAD_CHECK}
</body></html>
"""
    with open(os.path.join(out_dir, "report.html"), "w") as f:
        f.write(page)

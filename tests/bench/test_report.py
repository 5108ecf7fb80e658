"""bench/report on one small fixture, then its report.html opened in headless Chromium: every
<img> decoded (naturalWidth > 0) and every table present. Exit 77 (skipped) without chromium
or matplotlib.

  /usr/bin/python3 tests/bench/test_report.py --build BUILD
"""
import argparse
import csv
import html.parser
import math
import os
import re
import shutil
import subprocess
import sys
import tempfile

SOURCE = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
FIXTURE = os.path.join(SOURCE, "tests", "data", "box16")
# passthrough, both denoisers, and one mix (it has an alpha' map)
CHAINS = "noisy,nfor,cnn,nfor+sure+mix:net"
TABLES = ["error-relmse", "error-ssim", "speed", "runs"]
SKIP = 77


class PageParts(html.parser.HTMLParser):
    """The <img> sources, table ids and every other link of a page."""

    def __init__(self):
        super().__init__()
        self.images, self.tables, self.links = [], [], []

    def handle_starttag(self, tag, attrs):
        attrs = dict(attrs)
        if tag == "img":
            self.images.append(attrs.get("src", ""))
        elif tag == "table":
            self.tables.append(attrs.get("id", ""))
        for key in ("href", "src"):
            if key in attrs:
                self.links.append(attrs[key])


def fail(message):
    print(f"FAIL: {message}")
    sys.exit(1)


def load_check(dom):
    """The data-* counts the page's script wrote into #load-check."""
    tag = re.search(r'<p id="load-check"([^>]*)>', dom)
    if not tag:
        fail("no #load-check in Chromium's DOM")
    return dict(re.findall(r'data-(\w+)="([^"]*)"', tag.group(1)))


def main():
    parser = argparse.ArgumentParser()
    parser.add_argument("--build", required=True)
    args = parser.parse_args()
    chromium = shutil.which("chromium") or shutil.which("chromium-browser")
    if not chromium:
        print("SKIPPED: no chromium (apt install chromium; .ci/install-deps)")
        return SKIP
    try:
        import matplotlib  # noqa: F401
    except ImportError:
        print("SKIPPED: no matplotlib (apt install python3-matplotlib; .ci/install-deps)")
        return SKIP

    with tempfile.TemporaryDirectory(prefix="mcdn_report_") as out:
        report = subprocess.run([sys.executable, os.path.join(SOURCE, "bench", "report"),
                                 "--build", args.build, "--out", out, "--data", FIXTURE,
                                 "--chains", CHAINS, "--threads", "2"],
                                capture_output=True, text=True)
        print(report.stderr[-3000:])
        if report.returncode != 0:
            fail(f"bench/report exited {report.returncode}")

        with open(os.path.join(out, "results.csv")) as f:
            rows = list(csv.DictReader(f))
        if [r["chain"] for r in rows] != CHAINS.split(","):
            fail(f"results.csv has chains {[r['chain'] for r in rows]}")
        for row in rows:
            for key in ("relmse", "rmse", "smape", "ssim", "wall_s", "peak_rss_mb", "stage_x_baseline"):
                if not math.isfinite(float(row[key])):
                    fail(f"{row['chain']}: {key} = {row[key]}")
            if row["chain"] != "noisy" and float(row["relmse"]) >= float(rows[0]["relmse"]):
                fail(f"{row['chain']} relMSE {row['relmse']} not below the noisy input's {rows[0]['relmse']}")

        page = os.path.join(out, "report.html")
        parts = PageParts()
        with open(page) as f:
            parts.feed(f.read())
        for link in parts.links:  # offline: relative links to files that exist
            if "://" in link or link.startswith("/") or not os.path.exists(os.path.join(out, link)):
                fail(f"link {link!r} is not a relative path to a file in the report")
        for kind in ("_relmse.png", "_alpha.png", "reference.png", "plots/pareto.png",
                     "plots/error_vs_spp.png", "plots/time_vs_pixels.png"):
            if not any(kind in src for src in parts.images):
                fail(f"no <img> of {kind}")
        if sorted(parts.tables) != sorted(TABLES):
            fail(f"tables {parts.tables}, expected {TABLES}")

        dom = subprocess.run([chromium, "--headless", "--disable-gpu", "--no-sandbox",
                              f"--user-data-dir={os.path.join(out, 'chromium')}",
                              "--virtual-time-budget=10000", "--dump-dom", "file://" + page],
                             capture_output=True, text=True, timeout=120).stdout
        check = load_check(dom)
        print(f"Chromium: {check}")
        if int(check.get("images", -1)) != len(parts.images):
            fail(f"Chromium saw {check.get('images')} images, the page has {len(parts.images)}")
        if check.get("broken") != "0":
            fail(f"{check.get('broken')} images did not load in Chromium: {dom[dom.find('load-check'):][:400]}")
        if int(check.get("tables", -1)) != len(TABLES):
            fail(f"Chromium saw {check.get('tables')} tables")
        for table_id in TABLES:
            if f'<table id="{table_id}"' not in dom:
                fail(f"table {table_id} missing from Chromium's DOM")
    print(f"OK: {len(parts.images)} images and {len(TABLES)} tables loaded in Chromium")
    return 0


if __name__ == "__main__":
    sys.exit(main())

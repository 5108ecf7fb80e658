"""The benchmark report (bench/report): every chain on every scene x spp -> CSV, plots, HTML."""

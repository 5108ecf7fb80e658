"""mcdenoise: Monte Carlo render denoisers on OpenImageIO.ImageBuf.

The ops (read_inputs, prefilter, nfor, cnn, sure, mix, denoise, metrics, ...) come from the
compiled module `mcdenoise._mcdenoise`; `python3 -m mcdenoise.shot` runs a shot's frames
on a Dask cluster (mcdenoise/shot.py).
"""
from ._mcdenoise import *  # noqa: F401,F403 (the ops, as the compiled module names them)
from ._mcdenoise import __version__  # noqa: F401

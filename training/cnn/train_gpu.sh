#!/usr/bin/env bash
# Trains on a CUDA machine from patches.py's compact sets: several runs at once, one process
# each sharing the GPU, each for MINUTES; their states, curves, weights and logs are packed
# into OUT/NAME.tar, one per run (what a machine with no access to the dataset can send
# back; unpack into $MCDN_CACHE/cnn here: export.py --run NAME, train.py --run NAME --resume).
#   training/cnn/train_gpu.sh PATCHES VAL_PATCHES OUT MINUTES 'NAME:train.py args' ...
# e.g. (the run of issue 47; `w24` is export.py --run w24 here once unpacked into
# $MCDN_CACHE/cnn):
#   training/cnn/train_gpu.sh p.npz v.npz out 8 'w16:--widths 16,32,48' 'w24:--widths 24,48,64'
set -euo pipefail
patches=$1 val=$2 out=$3 minutes=$4
shift 4
export PYTHONUNBUFFERED=1 MCDN_CACHE=${MCDN_CACHE:-/tmp/mcdn-cache}
here=$(cd "$(dirname "$0")" && pwd)
mkdir -p "$out"
pids=()
for run in "$@"; do
  name=${run%%:*}
  # shellcheck disable=SC2086  # the run's arguments are words
  "${PYTHON:-python3}" "$here/train.py" --run "$name" --patches "$patches" --val-patches "$val" --device "${MCDN_DEVICE:-cuda}" \
    --minutes "$minutes" ${run#*:} >"$MCDN_CACHE/$name.log" 2>&1 &
  pids+=($!)
done
status=0
for pid in "${pids[@]}"; do wait "$pid" || status=1; done
for run in "$@"; do
  name=${run%%:*}
  mkdir -p "$MCDN_CACHE/cnn/$name"
  cp "$MCDN_CACHE/$name.log" "$MCDN_CACHE/cnn/$name/train.log"
  tar -C "$MCDN_CACHE/cnn" -cf "$out/$name.tar" "$name"
done
exit $status

#!/bin/bash
# Train the real run's planned experiments on a GPU machine that has torch but not the geometry packages,
# as the committed results were made (an H100 with 16 cores, 16 jobs sharing the GPU through MPS).
#
#   bash scripts/gpu_train.sh WHEELS_DIR PACKED_PSB OUT_DIR STOP_AFTER_MIN HARD_LIMIT_S NOTEBOOK...
#
# The plain process pool (--backend loky), so that Dask need not be carried there.
# WHEELS_DIR: py3.12 wheels of trimesh, libigl, potpourri3d and gco-wrapper (its ctypes library loads on any
# CPython, so the cp311 wheel is unzipped as it is); PACKED_PSB: made by `python scripts/pack_psb.py pack`.
# Writes OUT_DIR/runs.tgz (results/runs plus the models the notebooks render) and OUT_DIR/log.txt; unpack
# runs.tgz in the repository root, then `make reproduce DATA=real` reads the stored results.
wheels=$1; packed=$2; out=$3; stop=$4; hard=$5; shift 5
t0=$(date +%s)
python3 -m pip install -q --no-index --no-deps --no-compile --no-cache-dir --upgrade --target /tmp/site \
    "$wheels"/trimesh*.whl "$wheels"/libigl*.whl "$wheels"/potpourri3d*.whl || exit 1
python3 -m zipfile -e "$wheels"/gco_wrapper*.whl /tmp/site || exit 1
export PYTHONPATH=/tmp/site:$PWD ANSEG_DATA=/tmp/data ANSEG_CACHE=/tmp/cache PYTHONUNBUFFERED=1 \
    OMP_NUM_THREADS=1 NUMBA_NUM_THREADS=1
[ -d /tmp/data/LabeledDB_new ] || python3 scripts/pack_psb.py unpack "$packed" /tmp/data || exit 1
# MPS lets the jobs' small kernels share the GPU instead of time-slicing it (about 2x faster per run here)
nvidia-cuda-mps-control -d 2>/dev/null && echo "MPS daemon started"
echo "setup took $(( $(date +%s) - t0 )) s"
left=$(( hard - ($(date +%s) - t0) ))
# killed hard at the limit, so that what is stored still gets packed below
(timeout -s KILL $left python3 -m anseg.reproduce --data real --train-only --backend loky --workers "$(nproc)" \
    --stop-after "$stop" \
    --only "$@" 2>&1 | tr '\r' '\n' | grep "^\[anseg\]\|Error" > "$out"/log.txt)
pkill -9 -f "loky|multiprocessing"; sleep 1
models=$(python3 -c "
from anseg.experiments import planned_experiments
for e, x in planned_experiments('real', ['fig4', 'explore', 'fig12']):
    if e.dataset != 'psb' or e.category in ('Human', 'Teddy'):
        print(f'models/{e.key(x)}.pt')" | while read -r m; do [ -f "$m" ] && echo "$m"; done)
tar czf "$out"/runs.tgz results/runs $models
tail -40 "$out"/log.txt

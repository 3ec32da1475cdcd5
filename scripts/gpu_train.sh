#!/bin/bash
# Train the real run's planned experiments on a GPU machine that has torch but not the geometry packages,
# as the committed results were made (an H100 with 16 cores, 16 jobs sharing the GPU through MPS).
#
#   bash scripts/gpu_train.sh WHEELS_DIR PACKED_PSB OUT_DIR STOP_AFTER_MIN HARD_LIMIT_S NOTEBOOK...
#
# The plain process pool (--backend loky), so that Dask need not be carried there. WHEELS_DIR, PACKED_PSB: see
# gpu_setup.sh. Writes OUT_DIR/runs.tgz (results/runs plus the models the notebooks render) and OUT_DIR/log.txt;
# unpack runs.tgz in the repository root, then `make reproduce DATA=real` reads the stored results.
wheels=$1; packed=$2; out=$3; stop=$4; hard=$5; shift 5
source "$(dirname "$0")"/gpu_setup.sh "$wheels" "$packed"
left=$(( hard - ($(date +%s) - t0) ))
# killed hard at the limit, so that what is stored still gets packed below
(timeout -s KILL $left python3 -m anseg.study.reproduce --data real --train-only --backend loky --workers "$(nproc)" \
    --stop-after "$stop" \
    --only "$@" 2>&1 | tr '\r' '\n' | grep "^\[anseg\]\|Error" > "$out"/log.txt)
pkill -9 -f "loky|multiprocessing"; sleep 1
models=$(python3 -c "
from anseg.study.plan import planned_experiments
for e, x in planned_experiments('real', ['fig4', 'explore', 'fig12']):
    if e.dataset != 'psb' or e.category in ('Human', 'Teddy'):
        print(f'models/{e.key(x)}.pt')" | while read -r m; do [ -f "$m" ] && echo "$m"; done)
tar czf "$out"/runs.tgz results/runs $models
tail -40 "$out"/log.txt

#!/bin/bash
# Run a validation study (python -m anseg.study.validate) on a GPU machine, every cell of it side by side, one process per core.
#
#   bash scripts/gpu_validate.sh WHEELS_DIR PACKED_PSB OUT_DIR HARD_LIMIT_S VALIDATE_ARGUMENTS...
#
# e.g. ... --study confirm1 --arm default --arm "rw8:local_scale=relative,priority=weighted,density_range=8"
# WHEELS_DIR, PACKED_PSB: see gpu_setup.sh. Cells are stored as they finish (a cell killed at the limit is
# lost, the others are kept); writes OUT_DIR/validation.tgz (results/validation: the cells, the report; not the
# models) and OUT_DIR/log.txt. Unpack validation.tgz in the repository root: a study run here again trains
# only what is missing.
wheels=$1; packed=$2; out=$3; hard=$4; shift 4
source "$(dirname "$0")"/gpu_setup.sh "$wheels" "$packed"
left=$(( hard - ($(date +%s) - t0) ))
(timeout -s KILL $left python3 -m anseg.study.validate --backend loky --workers "$(nproc)" --quiet "$@" \
    > "$out"/log.txt 2>&1)
pkill -9 -f "loky|multiprocessing"; sleep 1
tar czf "$out"/validation.tgz --exclude=results/validation/models results/validation
tail -40 "$out"/log.txt

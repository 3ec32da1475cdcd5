# Sourced by gpu_train.sh and gpu_validate.sh: the geometry packages, the PSB meshes and the environment that a
# GPU machine with torch but nothing else needs, as the committed results were made (MPS sharing the GPU).
#
#   source scripts/gpu_setup.sh WHEELS_DIR PACKED_PSB
#
# WHEELS_DIR: py3.12 wheels of trimesh, libigl, potpourri3d and gco-wrapper (its ctypes library loads on any
# CPython, so the cp311 wheel is unzipped as it is); PACKED_PSB: made by `python scripts/pack_psb.py pack`.
# Sets t0 (the start, for the caller's time limit).
t0=$(date +%s)
python3 -m pip install -q --no-index --no-deps --no-compile --no-cache-dir --upgrade --target /tmp/site \
    "$1"/trimesh*.whl "$1"/libigl*.whl "$1"/potpourri3d*.whl || exit 1
python3 -m zipfile -e "$1"/gco_wrapper*.whl /tmp/site || exit 1
export PYTHONPATH=/tmp/site:$PWD ANSEG_DATA=/tmp/data ANSEG_CACHE=/tmp/cache PYTHONUNBUFFERED=1 \
    OMP_NUM_THREADS=1 NUMBA_NUM_THREADS=1
[ -d /tmp/data/LabeledDB_new ] || python3 scripts/pack_psb.py unpack "$2" /tmp/data || exit 1
# MPS lets the jobs' small kernels share the GPU instead of time-slicing it (about 2x faster per run here)
nvidia-cuda-mps-control -d 2>/dev/null && echo "MPS daemon started"
echo "setup took $(( $(date +%s) - t0 )) s"

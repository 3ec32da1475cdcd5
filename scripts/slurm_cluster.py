"""A Dask cluster on SLURM for the experiment runner (dask-jobqueue): one job per worker, one thread each.

    python scripts/slurm_cluster.py --jobs 16 [--gpu] [--memory 16GB] [--walltime 08:00:00]
    python scripts/slurm_cluster.py --print-job-script [--gpu]    # check the job script, no SLURM needed

It submits the worker jobs, prints the scheduler's address and keeps the
scheduler alive until interrupted; in another shell, on the login node:

    python -m anseg.study.reproduce --data real --train-only --scheduler tcp://HOST:PORT
    python -m anseg.study.validate --study width --arm default --arm wide:train.width=128 --scheduler tcp://HOST:PORT

With ``--gpu`` each job asks for a GPU and its worker declares the ``GPU``
resource, which the runs whose device is ``cuda`` wait for. Needs
``pip install dask-jobqueue``; the workers must see the same Python
environment and data folder ($ANSEG_DATA) as this script.
"""

from __future__ import annotations

import argparse
import time


def cluster(jobs_memory: str, walltime: str, gpu: bool):
    from dask_jobqueue import SLURMCluster

    return SLURMCluster(
        cores=1, processes=1, memory=jobs_memory, walltime=walltime,
        job_extra_directives=["--gres=gpu:1"] if gpu else [],
        worker_extra_args=["--resources", "GPU=1"] if gpu else [],
        job_script_prologue=["export OMP_NUM_THREADS=1 NUMBA_NUM_THREADS=1"],
        scheduler_options={"dashboard_address": None},
    )


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--jobs", type=int, default=4, help="worker jobs to submit (default: 4)")
    parser.add_argument("--gpu", action="store_true", help="one GPU per job, declared as the worker resource GPU=1")
    parser.add_argument("--memory", default="16GB", help="memory per job (default: 16GB)")
    parser.add_argument("--walltime", default="08:00:00", help="wall time per job (default: 08:00:00)")
    parser.add_argument("--print-job-script", action="store_true", help="print the job script and exit")
    args = parser.parse_args(argv)
    slurm = cluster(args.memory, args.walltime, args.gpu)
    try:
        if args.print_job_script:
            print(slurm.job_script())
            return
        slurm.scale(jobs=args.jobs)
        print(f"scheduler: {slurm.scheduler_address}  ({args.jobs} worker jobs submitted; Ctrl-C ends them)", flush=True)
        while True:
            time.sleep(60)
    finally:
        slurm.close()


if __name__ == "__main__":
    main()

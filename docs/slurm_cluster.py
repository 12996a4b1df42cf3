"""A Dask cluster on SLURM for surgopt's dask backend (README, "Running on a cluster"), through dask-jobqueue.

Run it on a login node, in the environment where surgopt is installed (the workers' jobs start the same Python):

    python docs/slurm_cluster.py --workers 16 --account mylab --partition normal --cache /shared/numba &
    surgopt port-place robot.instrument_count=3 cart.model=classic --backend dask --scheduler tcp://HOST:PORT

It submits one SLURM job per worker (one CPU, one thread each: numba's kernels are the speed, the workers the
parallelism), prints the scheduler's address for ``--scheduler``, and keeps the cluster up until it is stopped
(Ctrl-C cancels the jobs). Only the surgopt process writes the store; the workers compute chunks and send back
rows, so the store need not be on shared storage. ``--cache`` should be: surgopt compiles the kernels on one
worker first and the others load them from the shared numba cache (NUMBA_CACHE_DIR) instead of each compiling.
``--print-job-script`` prints the job script SLURM would get, and submits nothing.
"""
from __future__ import annotations

import argparse
import time


def slurm_cluster(workers_memory_gb: float = 4.0, walltime: str = "04:00:00", account: str | None = None,
                  partition: str | None = None, cache_dir: str | None = None, interface: str | None = None):
    """A ``dask_jobqueue.SLURMCluster`` whose jobs are one surgopt worker each: one CPU and one thread (numba
    brings its own speed; surgopt sets one numba thread per worker), ``workers_memory_gb`` of memory (a
    port-place chunk's rows and its model's tables; ``surgopt ... --dry-run`` gives the run's estimate), numba's
    cache folder ``cache_dir`` on shared storage exported to the worker. No job is submitted until it is
    scaled."""
    from dask_jobqueue import SLURMCluster

    prologue = [f"export NUMBA_CACHE_DIR={cache_dir}"] if cache_dir else []
    return SLURMCluster(cores=1, processes=1, memory=f"{workers_memory_gb:g}GB", walltime=walltime,
                        job_name="surgopt-worker", account=account, queue=partition, interface=interface,
                        job_script_prologue=prologue + ["export OMP_NUM_THREADS=1 OPENBLAS_NUM_THREADS=1"],
                        scheduler_options={"dashboard_address": None})


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--workers", type=int, default=8, help="SLURM jobs to start, one worker each")
    p.add_argument("--memory-gb", type=float, default=4.0, help="memory of each worker's job (GB)")
    p.add_argument("--walltime", default="04:00:00")
    p.add_argument("--account")
    p.add_argument("--partition")
    p.add_argument("--cache", help="numba's cache folder on storage every node shares")
    p.add_argument("--interface", help="the network interface the workers reach the scheduler on (e.g. ib0)")
    p.add_argument("--print-job-script", action="store_true", help="print the job script and submit nothing")
    a = p.parse_args()
    cluster = slurm_cluster(a.memory_gb, a.walltime, a.account, a.partition, a.cache, a.interface)
    if a.print_job_script:
        print(cluster.job_script())
        cluster.close()
        return
    cluster.scale(jobs=a.workers)
    print(f"surgopt ... --backend dask --scheduler {cluster.scheduler_address}", flush=True)
    try:
        while True:
            time.sleep(60)
    except KeyboardInterrupt:
        cluster.close()


if __name__ == "__main__":
    main()

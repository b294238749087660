"""A method comparison split into shards on a Dask cluster, over the twincal wheel.

Each Dask task runs one shard (``twincal.compare(..., shard="i/N", shard_out=PART)``) in a worker
process and appends its finished items to its partial file; the client then joins the parts with
``twincal.reduce``, which checks every item is there exactly once and renders the same tables as one
``compare``. A shard that dies is simply submitted again: it skips the items its file holds. twincal
itself knows nothing of Dask; any engine that can run a Python function N times works alike.

    python dask_compare.py                          # local cluster, the embedded scenario
    python dask_compare.py --scheduler tcp://host:8786 --data /shared/dataset --parts /shared/parts

With a remote scheduler, --data and --parts must be paths every worker sees (a shared file system).
"""

from __future__ import annotations

import argparse
import os
import sys

import twincal


def run_shard(data: str, methods: list[str], seeds: int, i: int, n: int, part: str) -> str:
    """One shard, in a worker: its items appended to `part` (resumes where a killed run stopped)."""
    twincal.compare(data, methods=methods, seeds=seeds, shard=f"{i}/{n}", shard_out=part)
    return part


def main(argv: list[str] | None = None) -> dict:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--data", help="dataset folder or file (default: the embedded scenario, generated into --parts)")
    p.add_argument("--methods", default="lm,pso", help="comma-separated methods (default lm,pso)")
    p.add_argument("--seeds", type=int, default=6)
    p.add_argument("--shards", type=int, default=3)
    p.add_argument("--workers", type=int, default=2, help="local cluster's worker processes")
    p.add_argument("--scheduler", help="address of a running Dask scheduler (default: start a local cluster)")
    p.add_argument("--parts", default="parts", help="folder of the partial files")
    p.add_argument("--out", help="also write the tables as JSON here")
    a = p.parse_args(argv)

    from dask.distributed import Client, LocalCluster

    os.makedirs(a.parts, exist_ok=True)
    data = a.data
    if data is None:
        # The embedded scenario's dataset, written once where the workers read it.
        data = os.path.join(a.parts, "dataset")
        os.makedirs(data, exist_ok=True)
        columns, _ = twincal.generate()
        with open(os.path.join(data, "dataset.csv"), "w") as f:
            f.write(twincal.to_csv(columns))
    data = os.path.abspath(data)
    methods = a.methods.split(",")
    parts = [os.path.abspath(os.path.join(a.parts, f"part-{i}-of-{a.shards}.jsonl")) for i in range(a.shards)]

    cluster = None if a.scheduler else LocalCluster(n_workers=a.workers, threads_per_worker=1, processes=True, dashboard_address=None)
    with Client(a.scheduler or cluster) as client:
        futures = [client.submit(run_shard, data, methods, a.seeds, i, a.shards, part, pure=False, retries=2) for i, part in enumerate(parts)]
        client.gather(futures)
    if cluster is not None:
        cluster.close()
    # reduce prints the comparison's tables, as `twincal reduce` does, and returns them.
    return twincal.reduce(parts, out=a.out)


if __name__ == "__main__":
    main(sys.argv[1:])

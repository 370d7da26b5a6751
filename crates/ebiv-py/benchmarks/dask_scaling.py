"""Scaling of ebiv.dask: one recording measured in shards by one worker, then by two, on a
local cluster whose workers each use one core (RAYON_NUM_THREADS=1), as the machines of a
cluster would each run one worker. Prints the index's cost, the wall times, the speed-up,
the overhead per shard (against the same worker measuring the whole recording as one
shard) and the workers' peak memory.

    ebiv simulate --example paper-rate --duration 10s -o paper10.raw
    python crates/ebiv-py/benchmarks/dask_scaling.py paper10.raw --shard 1s
"""

import argparse
import os
import resource
import time

os.environ["RAYON_NUM_THREADS"] = "1"  # inherited by the worker processes

import ebiv  # noqa: E402
import ebiv.dask  # noqa: E402
from dask.distributed import Client, LocalCluster  # noqa: E402


def peak_rss_mb() -> float:
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024


def run(rec: str, workers: int, shard: str, method: str) -> tuple:
    cluster = LocalCluster(n_workers=workers, threads_per_worker=1, processes=True,
                           host="127.0.0.1", dashboard_address=None)
    with Client(cluster) as client:
        started = time.perf_counter()
        ds = ebiv.dask.process(rec, method, client=client, shard=shard)
        seconds = time.perf_counter() - started
        peaks = client.run(peak_rss_mb)
    cluster.close()
    return seconds, ds, sorted(peaks.values())


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("recording")
    parser.add_argument("--shard", default="1s")
    parser.add_argument("--method", default="corrsum")
    args = parser.parse_args()
    rec = args.recording
    size_mb = os.path.getsize(rec) / 1e6

    started = time.perf_counter()
    ebiv.index(rec, force=True)
    index_s = time.perf_counter() - started
    events = ebiv.open(rec).report["events"]
    print(f"{rec}: {size_mb:.0f} MB, {events / 1e6:.1f} M events")
    print(f"index: {index_s:.2f} s ({events / index_s / 1e6:.0f} M events/s, one pass over the file)")

    span = ebiv.open(rec).time_range
    whole = f"{span[1] - span[0] + 1}us"
    n = len(ebiv.dask.shards(rec, args.method, shard=args.shard))
    one_shard, reference, _ = run(rec, 1, whole, args.method)
    one, ds1, peak1 = run(rec, 1, args.shard, args.method)
    two, ds2, peak2 = run(rec, 2, args.shard, args.method)
    assert ds1.identical(reference) and ds2.identical(reference), "sharded result differs"
    fields = reference.sizes["time"]
    print(f"{args.method}, default settings: {fields} fields in {n} shards of {args.shard}")
    print(f"1 worker, 1 shard:  {one_shard:.1f} s")
    print(f"1 worker, {n} shards: {one:.1f} s (overhead {(one - one_shard) / max(n - 1, 1):.3f} s per shard)")
    print(f"2 workers, {n} shards: {two:.1f} s")
    print(f"speed-up 2 workers / 1 worker: {one / two:.2f}x")
    print(f"peak memory per worker: {', '.join(f'{p:.0f}' for p in peak2)} MB "
          f"(1 worker over all shards {peak1[0]:.0f} MB; the recording is {size_mb:.0f} MB)")


if __name__ == "__main__":
    main()

"""convert_many on a Dask LocalCluster (2 worker processes, 1 thread each) and on the default process pool,
against `bvhc batch` on the same library in the same run, with every output compared byte for byte.

    cargo bench --bench batch          # writes target/batch-bench/library.jsonl (1,000 jobs)
    target/python/venv/bin/python crates/bvhc-py/bench/convert_many.py [target/batch-bench/library.jsonl]
"""

import json
import os
import pathlib
import shutil
import subprocess
import sys
import time

import bvhc

ROOT = pathlib.Path(__file__).resolve().parents[3]
BIN = os.environ.get("BVHC_BIN", str(ROOT / "target" / "release" / "bvhc"))


def jobs_into(manifest, folder):
    """The manifest's jobs with their outputs in `folder` (absolute paths)."""
    base = manifest.parent
    jobs = []
    for line in manifest.read_text().splitlines():
        job = json.loads(line)
        job["input"] = str((base / job["input"]).resolve())
        job["output"] = str(folder / pathlib.Path(job["output"]).name)
        jobs.append(job)
    return jobs


def fresh(folder):
    shutil.rmtree(folder, ignore_errors=True)
    folder.mkdir(parents=True)
    return folder


def main():
    manifest = pathlib.Path(sys.argv[1] if len(sys.argv) > 1 else ROOT / "target/batch-bench/library.jsonl").resolve()
    work = manifest.parent / "python"
    results = {}

    # bvhc batch on the same jobs, outputs in their own folder.
    batch_dir = fresh(work / "batch")
    batch_manifest = work / "batch.jsonl"
    batch_manifest.write_text("".join(json.dumps(j) + "\n" for j in jobs_into(manifest, batch_dir)))
    start = time.perf_counter()
    subprocess.run([BIN, "batch", str(batch_manifest), "-q"], check=False)
    results["bvhc batch"] = time.perf_counter() - start

    pool_jobs = jobs_into(manifest, fresh(work / "pool"))
    start = time.perf_counter()
    pool_reports = bvhc.convert_many(pool_jobs, progress=False)
    results["convert_many, process pool"] = time.perf_counter() - start

    try:
        from dask.distributed import Client, LocalCluster
    except ImportError:
        print("SKIPPED: dask[distributed] is not installed")
        dask_jobs, dask_reports = [], []
    else:
        dask_jobs = jobs_into(manifest, fresh(work / "dask"))
        with LocalCluster(n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None) as cluster:
            with Client(cluster) as client:
                start = time.perf_counter()
                dask_reports = bvhc.convert_many(dask_jobs, executor=client.get_executor(), progress=False)
                results["convert_many, Dask LocalCluster (2 workers)"] = time.perf_counter() - start

    count = len(pool_jobs)
    for name, seconds in results.items():
        ratio = seconds / results["bvhc batch"]
        print(f"{name}: {seconds:.2f} s ({count / seconds:.1f} jobs/s, {ratio:.2f}x bvhc batch's time)")
    differ = 0
    for jobs in (pool_jobs, dask_jobs):
        for job in jobs:
            a = pathlib.Path(job["output"])
            b = batch_dir / a.name
            differ += (a.read_bytes() if a.exists() else None) != (b.read_bytes() if b.exists() else None)
    failed = sum(r["status"] == "failed" for r in pool_reports + dask_reports)
    print(f"outputs differing from bvhc batch's: {differ}; failed reports: {failed}")


if __name__ == "__main__":
    main()

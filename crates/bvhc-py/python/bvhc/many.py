"""Converting a library: :func:`convert_many` runs jobs shaped as ``bvhc batch`` manifest lines on any
``concurrent.futures.Executor`` (a local process pool by default; a Dask cluster through
``client.get_executor()``; Ray through ``ray.util``'s executor), each job converted as ``bvhc batch`` converts
it, so the outputs are the same bytes.
"""

from __future__ import annotations

import concurrent.futures
import json
import os
import sys
from typing import Any, Callable, Dict, Iterable, List, Optional, Union

from . import _native

Job = Dict[str, Any]
Report = Dict[str, Any]


def options_table() -> List[Dict[str, Any]]:
    """Every conversion option (``bvhc options --list --json``): ``name`` (the keyword and the manifest's key),
    ``flag``, ``stage``, ``kind``, ``choices``, ``help``, ``inverse`` (the positive name a ``no_*`` switch also
    takes with a boolean), ``example`` and ``defaults`` (what each preset sets)."""
    return json.loads(_native.options_table())


def run_job(job: Job, force: bool = False, threads: Optional[int] = 1) -> Report:
    """Converts one job (``{"input", "output", "options"}``) in this process, as ``bvhc batch`` converts each of
    its jobs; its report (a dict: ``status`` ``converted``, ``up_to_date`` or ``failed``, ``seconds``,
    ``triangles``, ``cost``, ``output_hash``, ``error``, ``error_kind``). Never raises for a bad job: a bad
    option or input is a failed report. What :func:`convert_many` sends to its executor's workers."""
    return json.loads(_native.run_job(json.dumps(job), force, threads))


def run_jobs(jobs: List[Job], force: bool = False, threads: Optional[int] = 1) -> List[Report]:
    """:func:`run_job` for each of ``jobs`` in turn: one task of :func:`convert_many` (a chunk of jobs, so that an
    executor's per-task cost is paid once a chunk)."""
    return [run_job(job, force, threads) for job in jobs]


def _absolute(job: Job) -> Job:
    """The job with absolute paths: workers of a cluster may run elsewhere in the file system."""
    if not isinstance(job, dict):
        raise TypeError(f"a job is a dict {{'input', 'output', 'options'}}, not {type(job).__name__}")
    fixed = dict(job)
    for key in ("input", "output"):
        if isinstance(fixed.get(key), (str, os.PathLike)):
            fixed[key] = os.path.abspath(os.fspath(fixed[key]))
    options = fixed.get("options")
    if isinstance(options, dict) and isinstance(options.get("train_rays"), (str, os.PathLike)):
        fixed["options"] = dict(options, train_rays=os.path.abspath(os.fspath(options["train_rays"])))
    return fixed


def _lost(job: Job, error: BaseException) -> Report:
    """The report of a job whose worker failed (killed, or the executor broke)."""
    return {
        "source": "job",
        "input": job.get("input"),
        "output": job.get("output"),
        "status": "failed",
        "seconds": 0.0,
        "threads": 0,
        "triangles": None,
        "cost": None,
        "output_hash": None,
        "error": f"the worker running it failed: {type(error).__name__}: {error}",
        "error_kind": "internal",
    }


def _size(job: Job) -> int:
    try:
        return os.stat(job["input"]).st_size
    except (OSError, KeyError, TypeError):
        return 0


def convert_many(
    jobs: Iterable[Job],
    executor: Optional[concurrent.futures.Executor] = None,
    progress: Union[bool, Callable[[Report], None]] = True,
    *,
    force: bool = False,
    threads_per_job: Optional[int] = 1,
    retries: int = 1,
    jobs_per_task: Optional[int] = None,
) -> List[Report]:
    """Converts every job (dicts shaped as ``bvhc batch`` manifest lines: ``{"input": PATH, "output": PATH,
    "options": {NAME: VALUE}}``, the names of :func:`options_table`) and returns one report a job, in the jobs'
    order, failures included (``status == "failed"`` with ``error``); it raises only for a job that is not a
    dict.

    ``executor``: any ``concurrent.futures.Executor``; ``None`` makes a local process pool of one worker a
    core for the call. A Dask cluster's workers run the jobs through ``client.get_executor()``, Ray's through
    ``ray.util.ActorPool``-based executors or any ``Executor`` wrapping ``ray.remote``. Each job converts on
    ``threads_per_job`` threads (``None``: all the worker's cores); the bytes do not depend on it. Relative
    paths are made absolute here, before the jobs leave this process. A job whose worker dies (a killed
    process, a broken pool) is submitted again up to ``retries`` times (on a fresh pool when the default pool
    broke), then reported as failed; its output is never left half-written (outputs are written to a temporary
    file and renamed). The jobs go to the executor in tasks of ``jobs_per_task`` jobs (default: about 64 tasks,
    at most 16 jobs each), largest inputs first, so that a cluster's cost per task is paid once a chunk; a
    retried task skips the jobs its first run finished (their outputs are up to date). ``progress``: ``True`` prints a line on a terminal's stderr as jobs finish, a callable
    is called with each report as it arrives, ``False`` is silent.
    """
    jobs = [_absolute(job) for job in jobs]
    reports: List[Optional[Report]] = [None] * len(jobs)
    per_task = jobs_per_task or max(1, min(16, len(jobs) // 64))
    # Two jobs writing one file would race: the later one is refused before anything runs.
    writers: Dict[Any, int] = {}
    for index, job in enumerate(jobs):
        earlier = writers.setdefault(job.get("output"), index)
        if earlier != index:
            error = f"{job.get('output')}: also the output of job {earlier}"
            reports[index] = dict(_lost(job, ValueError()), error=error, error_kind="options")
    # Largest inputs first, so that long jobs do not start last; consecutive jobs of that order make a task.
    order = sorted((i for i in range(len(jobs)) if reports[i] is None), key=lambda i: -_size(jobs[i]))
    pending = [order[k : k + per_task] for k in range(0, len(order), per_task)]
    own = executor is None
    attempts: Dict[int, int] = {}
    done = 0
    show = progress if callable(progress) else None
    tty = progress is True and sys.stderr.isatty()
    while pending:
        pool = concurrent.futures.ProcessPoolExecutor(max_workers=os.cpu_count() or 1) if own else executor
        try:
            futures = {
                pool.submit(run_jobs, [jobs[i] for i in task], force, threads_per_job): task for task in pending
            }
            retry: List[List[int]] = []
            for future in concurrent.futures.as_completed(futures):
                task = futures[future]
                try:
                    finished = future.result()
                except Exception as error:  # the worker died or the executor broke
                    attempts[task[0]] = attempts.get(task[0], 0) + 1
                    if attempts[task[0]] <= retries:
                        retry.append(task)
                        continue
                    finished = [_lost(jobs[i], error) for i in task]
                for index, report in zip(task, finished):
                    reports[index] = report
                    done += 1
                    if show is not None:
                        show(report)
                if tty:
                    print(f"\r{done}/{len(jobs)} jobs", end="", file=sys.stderr, flush=True)
            pending = retry
        finally:
            if own:
                pool.shutdown(wait=True, cancel_futures=True)
    if tty:
        print(file=sys.stderr)
    return [report for report in reports if report is not None]

"""convert_many on the default process pool, on a real Dask LocalCluster (SKIPPED without ``distributed``) and
with a worker killed mid-job; the options table at the keyword door; the Python snippets of README.md and
docs/python.md run as written."""

import json
import os
import pathlib
import re
import signal
import subprocess
import threading
import time

import numpy as np
import pytest

import bvhc

ROOT = pathlib.Path(__file__).resolve().parents[3]
TEAPOT = ROOT / "fixtures" / "scenes" / "teapot.obj"
BIN = os.environ.get("BVHC_BIN", str(ROOT / "target" / "release" / "bvhc"))

OPTION_SETS = [{}, {"preset": "fast"}, {"preset": "fast", "no_splits": True, "max_leaf_size": 4}, {"splits": False}]


def library(tmp_path):
    """Jobs over the teapot with each option set, a job with a bad option and one with a missing input."""
    jobs = [
        {"input": str(TEAPOT), "output": str(tmp_path / f"out{i}.bvh"), "options": o} for i, o in enumerate(OPTION_SETS)
    ]
    jobs.append({"input": str(TEAPOT), "output": str(tmp_path / "bad.bvh"), "options": {"split_budget": 9}})
    jobs.append({"input": str(tmp_path / "missing.obj"), "output": str(tmp_path / "missing.bvh")})
    return jobs


def check_reports(jobs, reports, tmp_path):
    assert [r["status"] for r in reports] == ["converted"] * 4 + ["failed", "failed"]
    assert reports[4]["error_kind"] == "options" and "split_budget" in reports[4]["error"]
    assert reports[5]["error_kind"] == "unreadable" and "missing.obj" in reports[5]["error"]
    for job, report in zip(jobs[:4], reports):
        options = dict(job["options"])
        preset = options.pop("preset", "balanced")
        single = tmp_path / "single.bvh"
        bvhc.convert(job["input"], single, preset, force=True, **options)
        data = pathlib.Path(job["output"]).read_bytes()
        assert data == single.read_bytes(), job
        assert report["triangles"] == 6320 and report["cost"] > 0
        assert report["output_hash"].startswith("xxh3-64:")
    assert not (tmp_path / "bad.bvh").exists() and not (tmp_path / "missing.bvh").exists()


def test_convert_many_on_the_default_pool_matches_single_conversions_and_the_batch(tmp_path):
    jobs = library(tmp_path)
    seen = []
    reports = bvhc.convert_many(jobs, progress=seen.append)
    assert len(seen) == len(jobs)
    check_reports(jobs, reports, tmp_path)
    again = bvhc.convert_many(jobs, progress=False)
    assert [r["status"] for r in again[:4]] == ["up_to_date"] * 4
    assert [r["output_hash"] for r in again[:4]] == [r["output_hash"] for r in reports[:4]]
    # The same jobs as a manifest through `bvhc batch`: the same bytes, the same hashes.
    manifest = tmp_path / "library.jsonl"
    manifest.write_text("".join(json.dumps(dict(j, output=j["output"] + ".cli")) + "\n" for j in jobs))
    run = subprocess.run([BIN, "batch", str(manifest), "--json"], capture_output=True, text=True)
    assert run.returncode == 1, run.stderr  # two jobs fail
    lines = [json.loads(line) for line in run.stdout.splitlines()]
    assert [l["output_hash"] for l in lines[:4]] == [r["output_hash"] for r in reports[:4]]
    with pytest.raises(TypeError):
        bvhc.convert_many(["teapot.obj"])
    twice = bvhc.convert_many([jobs[0], jobs[0]], progress=False)
    assert [r["status"] for r in twice] == ["up_to_date", "failed"] and "also the output of job 0" in twice[1]["error"]


def test_convert_many_on_a_dask_local_cluster_gives_the_same_bytes(tmp_path):
    distributed = pytest.importorskip("distributed", reason="dask[distributed] is not installed")
    jobs = library(tmp_path)
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None) as cluster:
        with distributed.Client(cluster) as client:
            reports = bvhc.convert_many(jobs, executor=client.get_executor(), progress=False)
            pids = set(client.run(os.getpid).values())
    assert os.getpid() not in pids and len(pids) == 2  # the jobs ran in the cluster's worker processes
    check_reports(jobs, reports, tmp_path)


def pool_workers():
    """This process's forked children (the default pool's workers: the same command line as this process; a
    helper such as multiprocessing's resource tracker is started by its own command)."""
    own = pathlib.Path("/proc/self/cmdline").read_bytes()
    found = []
    for entry in pathlib.Path("/proc").iterdir():
        try:
            if not entry.name.isdigit():
                continue
            parent = int((entry / "stat").read_text().rsplit(")", 1)[1].split()[1])
            if parent == os.getpid() and (entry / "cmdline").read_bytes() == own:
                found.append(int(entry.name))
        except (OSError, ValueError, IndexError):
            pass
    return found


@pytest.mark.skipif(not pathlib.Path("/proc").is_dir(), reason="needs /proc to find the pool's workers")
@pytest.mark.parametrize("retries", [1, 0])
def test_a_worker_killed_mid_job_leaves_no_partial_file_and_the_job_is_retried_or_reported(tmp_path, retries):
    # A grid of 320,000 triangles converted with max-quality: a few seconds, long enough to kill its worker.
    n = 400
    xs, ys = np.meshgrid(np.arange(n + 1, dtype=np.float64), np.arange(n + 1, dtype=np.float64))
    vertices = np.stack([xs.ravel(), ys.ravel(), np.sin(xs.ravel()) * np.cos(ys.ravel())], 1)
    i = np.arange(n * (n + 1)).reshape(n, n + 1)[:, :n].ravel()
    faces = np.concatenate([np.stack([i, i + 1, i + n + 1], 1), np.stack([i + 1, i + n + 2, i + n + 1], 1)])
    grid = tmp_path / "grid.ply"
    with open(grid, "wb") as f:
        f.write(bvhc._ply_bytes(vertices, faces))
    out = tmp_path / "out"
    out.mkdir()
    jobs = [{"input": str(grid), "output": str(out / "grid.bvh"), "options": {"preset": "max-quality"}}]
    killed = []

    def kill_a_worker():
        deadline = time.monotonic() + 30
        while time.monotonic() < deadline and not killed:
            workers = pool_workers()
            if workers:
                time.sleep(1.0)  # the conversion is under way
                for pid in workers:
                    try:
                        os.kill(pid, signal.SIGKILL)
                        killed.append(pid)
                    except ProcessLookupError:
                        pass
            time.sleep(0.05)

    killer = threading.Thread(target=kill_a_worker)
    killer.start()
    reports = bvhc.convert_many(jobs, progress=False, retries=retries)
    killer.join()
    assert killed, "a worker was killed"
    leftovers = [p.name for p in out.iterdir() if p.name != "grid.bvh"]
    if retries:
        assert reports[0]["status"] == "converted", reports[0]
        assert bvhc.verify(out / "grid.bvh")
    else:
        assert reports[0]["status"] == "failed" and "worker" in reports[0]["error"], reports[0]
        assert not (out / "grid.bvh").exists()
        # A later run sweeps what the killed worker left and converts.
        assert bvhc.convert_many(jobs, progress=False)[0]["status"] == "converted"
        leftovers = [p.name for p in out.iterdir() if p.name != "grid.bvh"]
    assert leftovers == [], leftovers


def test_every_option_of_the_table_is_a_keyword_with_the_command_lines_meaning(tmp_path):
    rays = tmp_path / "rays.bin"
    record = np.array([0.0, 1.0, 10.0, 0.0, 0.0, -1.0, 0.0, np.inf], dtype="<f4")
    rays.write_bytes(np.tile(record, 64).tobytes())
    table = bvhc.options_table()
    assert "no_splits" in {o["name"] for o in table} and len({o["name"] for o in table}) == len(table)
    for option in table:
        value = str(rays) if option["kind"] == "path" else option["example"]
        given = {option["name"]: value}
        if option["name"] in ("animation_poses", "animation_window"):
            given["animation"] = True
        presets = ["fast", "balanced", "max-quality"]
        if option["name"] == "preset":
            presets, given = [value], {}
        for preset in presets:
            flags = ["options", "--preset", preset]
            for name, v in given.items():
                flags.append("--" + name.replace("_", "-"))
                if v is not True:
                    flags.append(str(v))
            run = subprocess.run([BIN, *flags], capture_output=True, text=True)
            if run.returncode == 2:
                with pytest.raises(bvhc.OptionsError):
                    bvhc.options(preset, **given)
                continue
            assert run.returncode == 0, run.stderr
            assert bvhc.options(preset, **given) == json.loads(run.stdout), (option["name"], preset)


def python_snippets(path):
    return re.findall(r"```python\n(.*?)```", (ROOT / path).read_text(), re.S)


@pytest.mark.parametrize("path", ["README.md", "docs/python.md", "docs/libraries.md"])
def test_the_docs_python_snippets_run_as_written(path, tmp_path, monkeypatch):
    snippets = python_snippets(path)
    assert snippets, f"{path} has Python snippets"
    (tmp_path / "fixtures").symlink_to(ROOT / "fixtures")
    monkeypatch.chdir(tmp_path)
    for number, snippet in enumerate(snippets):
        if "# not run:" in snippet:  # needs a cluster or a service the tests do not have
            continue
        try:
            exec(compile(snippet, f"{path} snippet {number + 1}", "exec"), {"__name__": "__main__"})
        except ImportError as error:
            pytest.skip(f"{path} snippet {number + 1} needs {error.name}")

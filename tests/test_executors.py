"""Where the work runs: in-process, a process pool, a Dask LocalCluster, a Dask scheduler + worker pair.

References: ``--workers 1`` (everything in this process, no executor) for the
same seed; every scenario carries its own seed, so any executor must give
the same JSON numbers.  Dask tests skip cleanly without the ``dask`` extra.
"""

import contextlib
import json
import os
import socket
import subprocess
import sys
import time
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import pytest

from sensorplan import ConfigError, ExecutorError, example_case, verify_layouts
from sensorplan._executors import executor_for, map_ordered
from sensorplan.cli import main

ROOT = Path(__file__).resolve().parents[1]
SMALL = dict(n_locations=2, n_controls=2, n_crossings=3, seed=4)
CLI_SMALL = ["verify", "--example", "simply-supported", "--layout", "4,16", "--layout", "0,10,20",
             "--scenarios", "2", "--verify-crossings", "3", "--seed", "4", "--quiet"]


def has_dask():
    try:
        import distributed  # noqa: F401
    except ImportError:
        return False
    return True


needs_dask = pytest.mark.skipif(not has_dask(), reason="the dask extra is not installed")


def free_port():
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def one_error_line(capsys):
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1, err
    return err[0]


def test_map_ordered_returns_results_in_submission_order():
    # reference: the list comprehension; the chunks are finished out of order by the slow first item
    items = [0.3, 0.0, 0.01, 0.0, 0.02, 0.0, 0.0]

    def nap(x):
        time.sleep(x)
        return x

    seen = []
    with ThreadPoolExecutor(3) as pool:
        out = map_ordered(pool, nap, items, chunksize=2, progress=lambda done, total: seen.append((done, total)))
    assert out == items
    assert seen == [(k, len(items)) for k in range(1, len(items) + 1)]
    assert map_ordered(None, abs, [-2, 3]) == [2, 3]


@pytest.mark.parametrize("workers", [0, -1, 1.5, True])
def test_executor_rejects_bad_worker_counts(workers):
    with pytest.raises(ConfigError, match="workers"):
        with executor_for(workers):
            pass


def test_dead_pool_worker_is_a_clear_error():
    with executor_for(2) as pool:
        with pytest.raises(ExecutorError, match="worker died"):
            map_ordered(pool, os._exit, [3])


def test_missing_dask_names_the_extra(tmp_path, capsys, monkeypatch):
    for name in [m for m in sys.modules if m == "distributed" or m.startswith("distributed.")]:
        monkeypatch.delitem(sys.modules, name)
    monkeypatch.setitem(sys.modules, "distributed", None)  # import distributed -> ImportError
    assert main(CLI_SMALL + ["--scheduler", "local", "--out", str(tmp_path)]) == 1
    line = one_error_line(capsys)
    assert "--scheduler" in line and "pip install -e '.[dask]'" in line
    assert not list(tmp_path.iterdir())  # nothing written


def test_malformed_scheduler_address_is_one_line(tmp_path, capsys):
    pytest.importorskip("distributed")
    assert main(CLI_SMALL + ["--scheduler", "no-port-here", "--out", str(tmp_path)]) == 1
    assert "--scheduler" in one_error_line(capsys)


@needs_dask
def test_unreachable_scheduler_fails_fast_with_one_line(tmp_path, capsys):
    address = f"tcp://127.0.0.1:{free_port()}"  # nothing listens there
    t0 = time.perf_counter()
    assert main(CLI_SMALL + ["--scheduler", address, "--scheduler-timeout", "1", "--out", str(tmp_path)]) == 1
    elapsed = time.perf_counter() - t0
    line = one_error_line(capsys)
    assert "--scheduler" in line and address in line and "within 1 s" in line
    assert elapsed < 8.0
    assert not list(tmp_path.iterdir())


@needs_dask
@pytest.mark.slow
def test_local_cluster_gives_the_numbers_of_one_worker():
    case = example_case("simply-supported")
    layouts = [[4.0, 16.0], [0.0, 10.0, 20.0]]
    one = verify_layouts(case, layouts, workers=1, **SMALL).to_dict()
    cluster = verify_layouts(case, layouts, workers=2, scheduler="local", **SMALL).to_dict()
    assert json.dumps(cluster, sort_keys=True) == json.dumps(one, sort_keys=True)


@needs_dask
def test_dead_dask_worker_is_a_clear_error():
    import dask

    with dask.config.set({"distributed.scheduler.allowed-failures": 0}):
        with executor_for(1, "local") as cluster:
            with pytest.raises(ExecutorError, match="worker died"):
                map_ordered(cluster, os._exit, [3])


@contextlib.contextmanager
def dask_process(*args):
    """``python -m dask ARGS`` with this worktree's sensorplan importable; killed on exit."""
    env = dict(os.environ, PYTHONPATH=os.pathsep.join([str(ROOT), os.environ.get("PYTHONPATH", "")]))
    proc = subprocess.Popen([sys.executable, "-m", "dask", *args], env=env, cwd=ROOT,
                            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, start_new_session=True)
    try:
        if args[0] == "scheduler":  # wait until it listens (the machine may be busy)
            port = int(args[args.index("--port") + 1])
            deadline = time.monotonic() + 60
            while True:
                with socket.socket() as s:
                    if s.connect_ex(("127.0.0.1", port)) == 0:
                        break
                assert proc.poll() is None and time.monotonic() < deadline, "the dask scheduler did not start"
                time.sleep(0.2)
        yield proc
    finally:
        proc.terminate()
        try:
            proc.wait(timeout=10)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait(timeout=10)


@needs_dask
@pytest.mark.slow
def test_cli_on_a_running_scheduler_and_worker_equals_one_worker(tmp_path, capsys):
    port = free_port()
    address = f"tcp://127.0.0.1:{port}"
    ref = tmp_path / "one.json"
    assert main(CLI_SMALL + ["--workers", "1", "--json", str(ref), "--out", str(tmp_path / "a")]) == 0
    with dask_process("scheduler", "--host", "127.0.0.1", "--port", str(port), "--no-dashboard"):
        # a scheduler without workers: a clear error after the timeout, not a hang
        t0 = time.perf_counter()
        assert main(CLI_SMALL + ["--scheduler", address, "--scheduler-timeout", "3",
                                 "--out", str(tmp_path / "b")]) == 1
        assert time.perf_counter() - t0 < 30.0
        line = one_error_line(capsys)
        assert "no worker" in line and f"dask worker {address}" in line
        with dask_process("worker", address, "--nworkers", "1", "--nthreads", "1", "--no-dashboard"):
            got = tmp_path / "dask.json"
            assert main(CLI_SMALL + ["--scheduler", address, "--scheduler-timeout", "30", "--json", str(got),
                                     "--out", str(tmp_path / "c")]) == 0
    assert json.loads(got.read_text()) == json.loads(ref.read_text())


def test_verify_options_reach_verify_layouts_once_per_severity(tmp_path, capsys):
    # reference: verify_layouts called directly with the same options, one call per severity
    js = tmp_path / "v.json"
    assert main(["verify", "--example", "simply-supported", "--layout", "4,16", "--scenarios", "1",
                 "--verify-crossings", "3", "--seed", "2", "--severity", "0.1,0.3", "--length", "3",
                 "--false-alarm", "0.1", "--nuisance", "levels", "--json", str(js), "--out", str(tmp_path)]) == 0
    got = json.loads(js.read_text())
    assert got["severities"] == [0.1, 0.3]
    case = example_case("simply-supported")
    for severity, entry in zip((0.1, 0.3), got["verifications"]):
        ref = verify_layouts(case, [[4.0, 16.0]], n_locations=1, n_crossings=3, seed=2, severity=severity,
                             length=3.0, false_alarm=0.1, nuisance="levels")
        assert entry == json.loads(json.dumps(ref.to_dict()))
    printed = capsys.readouterr().out
    assert printed.count("Verification:") == 2 and "10 % over 3 m" in printed and "levels nuisance" in printed
    assert (tmp_path / "verification-10pct.png").exists() and (tmp_path / "verification-30pct.png").exists()


def test_bad_severity_is_one_line(tmp_path, capsys):
    assert main(CLI_SMALL + ["--severity", "0.1,1.5", "--out", str(tmp_path)]) == 1
    assert "severity" in one_error_line(capsys)
    assert not list(tmp_path.iterdir())


@needs_dask
def test_diagnose_on_a_local_cluster_equals_one_process():
    # issue 18: diagnose accepts --workers/--scheduler like verify; the reference is the screening in
    # this process (workers=1), the result must not depend on where the effects were screened
    from dataclasses import replace

    import sensorplan as sp
    from sensorplan.diagnosis.diagnose import diagnose

    case = example_case("openlab-like")
    case = replace(case.with_mesh(sp.Mesh.uniform(case.bridge, 8)), sweep=sp.LoadSweep.from_range(0.0, 32.0, 1.0))
    data = sp.simulate_crossings(case, 4, noise=True, rng=5)
    effects = ["sensor_offset", "vertical_support_spring"]
    one = diagnose(case, data, effects=effects, workers=1).to_dict()
    cluster = diagnose(case, data, effects=effects, workers=2, scheduler="local").to_dict()
    assert json.dumps(cluster, sort_keys=True, default=str) == json.dumps(one, sort_keys=True, default=str)

"""Sweeps on a real Dask cluster on loopback: one scheduler and two worker processes started
here (``dask scheduler`` / ``dask worker`` subprocesses) and torn down after the module."""
from __future__ import annotations

import collections
import json
import os
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path

import numpy as np
import pytest

import terradyn.sweep as sw
from terradyn.errors import InputError

from test_sweep import SMALL, direct, heavy_spec

distributed = pytest.importorskip("distributed")

ENV = {**os.environ, "NUMBA_NUM_THREADS": "1", "OMP_NUM_THREADS": "1", "OPENBLAS_NUM_THREADS": "1",
       "DASK_DISTRIBUTED__WORKER__DAEMON": "False"}


class Cluster:
    def __init__(self, tmp: Path):
        self.tmp = tmp
        self.file = tmp / "scheduler.json"
        self.procs: list[subprocess.Popen] = []
        self.workers: list[subprocess.Popen] = []
        self.scheduler = self._start(["scheduler", "--host", "127.0.0.1", "--port", "0", "--no-dashboard",
                                      "--scheduler-file", str(self.file)], "scheduler")
        deadline = time.monotonic() + 60
        while not self.file.exists() or not self.file.read_text().strip():
            if time.monotonic() > deadline or self.scheduler.poll() is not None:
                raise RuntimeError("dask scheduler did not start: " + self._log("scheduler"))
            time.sleep(0.1)
        self.address = json.loads(self.file.read_text())["address"]
        assert self.address.startswith("tcp://127.0.0.1:")
        for _ in range(2):
            self.add_worker()
        self.wait_workers(2)

    def _start(self, args, name):
        log = open(self.tmp / f"{name}-{len(self.procs)}.log", "w")
        p = subprocess.Popen([sys.executable, "-m", "dask", *args], stdout=log, stderr=subprocess.STDOUT,
                             env=ENV, start_new_session=True)
        self.procs.append(p)
        return p

    def _log(self, name):
        return "\n".join(f.read_text()[-2000:] for f in self.tmp.glob(f"{name}-*.log"))

    def add_worker(self):
        # --no-nanny: the process we kill is the worker itself, not a nanny that restarts it.
        w = self._start(["worker", "--scheduler-file", str(self.file), "--host", "127.0.0.1", "--nthreads", "1",
                         "--no-nanny", "--no-dashboard", "--death-timeout", "60"], "worker")
        self.workers.append(w)
        return w

    def wait_workers(self, n, timeout=90):
        with distributed.Client(self.address, timeout="30s") as c:
            c.wait_for_workers(n, timeout=timeout)
            return c.scheduler_info(n_workers=-1)["workers"]

    def close(self):
        for p in self.procs:
            if p.poll() is None:
                os.killpg(p.pid, signal.SIGTERM)
        for p in self.procs:
            try:
                p.wait(3)
            except subprocess.TimeoutExpired:
                os.killpg(p.pid, signal.SIGKILL)
                p.wait(5)


@pytest.fixture(scope="module")
def cluster(tmp_path_factory):
    c = Cluster(tmp_path_factory.mktemp("dask"))
    try:
        yield c
    finally:
        c.close()


def test_dask_gives_the_same_numbers_as_the_local_pool(cluster, tmp_path):
    spec = sw.parse(SMALL)
    d = sw.run(spec, tmp_path / "dask.sweep", scheduler=cluster.address)
    assert (d.executor, d.done, d.failed) == ("dask", 6, {})
    p = sw.run(spec, tmp_path / "pool.sweep", workers=2)
    assert (p.executor, p.workers, p.done, p.failed) == ("local", 2, 6, {})
    dd, pp = sw.collect(tmp_path / "dask.sweep"), sw.collect(tmp_path / "pool.sweep")
    assert list(dd.case_id.values) == list(pp.case_id.values) == [c.id for c in spec.cases]
    for v in ("Fx", "Fz", "torque"):
        np.testing.assert_array_equal(dd[v].values, pp[v].values)
    for i, c in enumerate(spec.cases):  # and both are the plain simulation
        np.testing.assert_array_equal(dd.Fz.isel(case=i).values, direct(c.params).Fz.values)
    # computed elsewhere: Dask worker processes, pool processes, not this one
    pids = lambda store: {int(sw.Store(store).read_case(c.id).attrs["sweep_pid"]) for c in spec.cases}  # noqa: E731
    worker_pids = {w.pid for w in cluster.workers}
    assert pids(tmp_path / "dask.sweep") <= worker_pids
    assert os.getpid() not in pids(tmp_path / "pool.sweep")
    assert not pids(tmp_path / "pool.sweep") & worker_pids


def test_environment_variable_names_the_scheduler(cluster, tmp_path, monkeypatch):
    monkeypatch.setenv(sw.SCHEDULER_ENV, cluster.address)
    s = sw.run(sw.parse(SMALL.replace("[6.0, 7.62]", "[5.0]")), tmp_path / "e.sweep")
    assert (s.executor, s.done) == ("dask", 3)


def test_a_failing_case_on_dask_is_recorded_and_the_others_finish(cluster, tmp_path):
    spec = sw.parse(SMALL)
    bad = spec.cases[1]
    params = json.loads(json.dumps(bad.params))
    params["model"]["medium"] = "moon dust"  # slips past the plan: fails on the worker
    spec.cases[1] = sw.Case(bad.id, params, bad.varied)
    s = sw.run(spec, tmp_path / "f.sweep", scheduler=cluster.address, retries=1)
    assert s.done == 5 and list(s.failed) == [bad.id] and "moon dust" in s.failed[bad.id]
    st = sw.status(tmp_path / "f.sweep")
    assert (st["done"], st["failed"]) == (5, 1) and "InputError" in st["failures"][bad.id]["error"]


def test_unreachable_scheduler_is_an_input_error(tmp_path, monkeypatch):
    monkeypatch.setattr("terradyn.sweep.execute.CONNECT_TIMEOUT", "1s")
    with pytest.raises(InputError, match="scheduler"):
        sw.run(sw.parse(SMALL), tmp_path / "u.sweep", scheduler="tcp://127.0.0.1:9")


def test_worker_killed_mid_sweep_does_not_lose_the_sweep(cluster, tmp_path):
    n = 40
    spec = sw.parse(heavy_spec(n))
    store = tmp_path / "k.sweep"
    result, errors = {}, []

    def drive():
        try:
            result["s"] = sw.run(spec, store, scheduler=cluster.address)
        except BaseException as e:  # reported below
            errors.append(e)

    victim = cluster.workers[0]
    t = threading.Thread(target=drive)
    t.start()
    try:
        deadline = time.monotonic() + 120
        while time.monotonic() < deadline and t.is_alive():
            ev = sw.Store(store).events()
            pids = [e["pid"] for e in ev if e["event"] == "case-done"]
            if len(pids) >= 3 and victim.pid in pids:  # the victim has been working on it
                break
            time.sleep(0.01)
        os.kill(victim.pid, signal.SIGKILL)
        victim.wait(10)
        done_at_kill = len(sw.Store(store).done_ids())
        t.join(180)
        assert not t.is_alive() and not errors, errors
        assert 3 <= done_at_kill < n, "the kill must land mid-sweep"
        s = result["s"]
        assert (s.done, s.failed) == (n, {})
        ev = sw.Store(store).events()
        by_pid = collections.Counter(e["pid"] for e in ev if e["event"] == "case-done")
        assert victim.pid in by_pid and len(by_pid) == 2  # both workers did part of it
        assert set(collections.Counter(e["case"] for e in ev if e["event"] == "case-done").values()) == {1}
        ds = sw.collect(store)
        for i, c in enumerate(spec.cases[::7]):
            j = spec.cases.index(c)
            np.testing.assert_array_equal(ds.Fz.isel(case=j).values, direct(c.params).Fz.values)
    finally:
        cluster.workers.remove(victim)
        cluster.add_worker()  # leave two workers for any later test
        cluster.wait_workers(2)


def test_an_existing_client_in_the_process_is_reused(cluster, tmp_path):
    with distributed.Client(cluster.address) as c:
        seen = []
        orig = c.submit

        def spy(*a, **k):
            seen.append(k.get("key"))
            return orig(*a, **k)

        c.submit = spy
        s = sw.run(sw.parse(SMALL.replace("[6.0, 7.62]", "[5.5]")), tmp_path / "r.sweep", scheduler=cluster.address)
        assert (s.executor, s.done) == ("dask", 3) and len(seen) == 3
        assert c.status == "running"  # not closed by the sweep

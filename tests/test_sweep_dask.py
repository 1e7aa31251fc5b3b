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
from terradyn.sweep.execute import task_key

from test_sweep import SMALL, direct, heavy_spec

distributed = pytest.importorskip("distributed")

ENV = {**os.environ, "NUMBA_NUM_THREADS": "1", "OMP_NUM_THREADS": "1", "OPENBLAS_NUM_THREADS": "1",
       "DASK_DISTRIBUTED__WORKER__DAEMON": "False",
       # the workers' logs of executed tasks are the test's record of what was computed
       "DASK_DISTRIBUTED__ADMIN__LOW_LEVEL_LOG_LENGTH": "100000"}


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
        deadline = time.monotonic() + 3
        for p in self.procs:
            try:
                p.wait(max(0.1, deadline - time.monotonic()))
            except subprocess.TimeoutExpired:
                os.killpg(p.pid, signal.SIGKILL)
        for p in self.procs:  # a loaded machine may take a while even after SIGKILL
            try:
                p.wait(60)
            except subprocess.TimeoutExpired:
                pass


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



def slow_spec(n_lengths: int) -> str:
    """2 x ``n_lengths`` cases, ids unlike :func:`heavy_spec`'s: for each leg length a short
    case (8000 elements x 8000 angles, ~0.1 s) and a long one (x 256000 angles, ~4 s of CPU on
    one thread: the RFT engine got faster, and at 64000 angles a long case could end inside the
    window below),
    so that the driver can be killed while a long case has surely not finished on its worker:
    one that started less than 2 s ago (wall time) has at least 2 s of CPU to go, however
    loaded the machine is."""
    return (heavy_spec(n_lengths).replace('name = "heavy"', 'name = "slow"')
            .replace("elements = 2000", "elements = 8000").replace("n_theta = 2000\n", "")
            + "motion.n_theta = [8000, 256000]\n")


def _worker_probes():
    """Functions for ``Client.run`` (defined here so cloudpickle ships them by value: the
    workers cannot import this module). ``executing``: key -> seconds since it started, for
    the tasks a worker is running now (including cancelled ones still running); ``executed``:
    keys of every execution the worker finished (its stimulus log, one entry per execution);
    ``cancelled_running``: keys the scheduler released while they were executing there (its
    transition log: executing -> cancelled), i.e. orphans that ran on without a client."""
    def executing(dask_worker):
        now = time.time()
        return {str(ts.key): now - ts.start_time for ts in list(dask_worker.state.executing)
                if ts.start_time is not None}

    def executed(dask_worker):
        return [str(ev.key) for ev in list(dask_worker.state.stimulus_log)
                if type(ev).__name__ in ("ExecuteSuccessEvent", "ExecuteFailureEvent")]

    def cancelled_running(dask_worker):
        return [str(e[0]) for e in list(dask_worker.state.log)
                if len(e) == 7 and e[1] == "executing" and e[3] == "cancelled"]

    return executing, executed, cancelled_running


def test_driver_killed_mid_sweep_on_dask_then_rerun_loses_nothing_and_repeats_nothing(cluster, tmp_path):
    """The driver (``terradyn sweep run --scheduler``, a subprocess) is SIGKILLed while cases
    run on the Dask workers, just after one of them started a long case; the sweep is rerun.

    Lost: a case of the plan missing from the store afterwards, or not the plain simulation's
    numbers. Run twice: a case whose result was stored before the kill (its file present
    after it) computed again, or any case stored twice. Computations are counted from the
    workers' own logs (every execution of every task, its key naming the case and the driver
    run that submitted it), not from the store, which never hears of a computation whose
    result did not reach it. A case in flight when the driver died had no stored result:
    the rerun computes it once more, which is allowed, and its orphaned task, which Dask
    cannot stop, runs on to its end on the worker after the scheduler has dropped it. The
    test checks that such an orphan existed and finished, and left nothing in the store
    (only the driver writes it: the orphan's result goes nowhere)."""
    executing, executed, cancelled_running = _worker_probes()
    spec_path = tmp_path / "slow.toml"
    spec_path.write_text(slow_spec(3))
    spec = sw.load(spec_path)
    n, ids = len(spec.cases), {c.id for c in spec.cases}
    long_ids = {c.id for c in spec.cases if c.params["motion"]["n_theta"] == 256000}
    store = tmp_path / "d.sweep"
    ours = lambda key: key.startswith("terradyn-case-") and key.split("-")[2] in ids  # noqa: E731
    case_of, run_of = (lambda key: key.split("-")[2]), (lambda key: key.split("-")[3])  # noqa: E731
    cmd = [sys.executable, "-m", "terradyn", "sweep", "run", str(spec_path), "--store", str(store),
           "--scheduler", cluster.address, "-q"]
    with distributed.Client(cluster.address, timeout="30s", set_as_default=False) as c:
        proc = subprocess.Popen(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, env=ENV,
                                start_new_session=True)
        fresh = set()
        try:
            deadline = time.monotonic() + 300
            while time.monotonic() < deadline and proc.poll() is None:
                if len(sw.Store(store).done_ids()) >= 2:
                    running = {k: age for w in c.run(executing).values() for k, age in w.items() if ours(k)}
                    fresh = {k for k, age in running.items() if age < 2.0 and case_of(k) in long_ids}
                    if fresh:  # a long case started < 2 s ago: it has 2 s of CPU or more to go
                        break
                time.sleep(0.01)
            assert proc.poll() is None, ("the driver ended before it could be killed: "
                                         + proc.stderr.read().decode()[-2000:])
            os.kill(proc.pid, signal.SIGKILL)
            proc.wait(10)
        finally:
            if proc.poll() is None:
                os.killpg(proc.pid, signal.SIGKILL)
                proc.wait(10)
        assert proc.returncode == -signal.SIGKILL, proc.stderr.read().decode()[-2000:]
        assert fresh, "no long case had just started when the driver was killed"
        st = sw.Store(store)
        done_before = st.done_ids()
        assert 2 <= len(done_before) < n, "the kill must land mid-sweep"
        (killed,) = [e["run"] for e in st.events() if e["event"] == "run-start"]
        assert fresh == {task_key(case_of(k), killed) for k in fresh}

        s = sw.run(spec, store, scheduler=cluster.address)  # the rerun, while the orphan may still run
        after_rerun = {p.name: (p.stat().st_ino, p.stat().st_mtime_ns, p.stat().st_size)
                       for p in [*store.joinpath("cases").iterdir(), store / "events.jsonl"]}
        assert (s.executor, s.skipped, s.done, s.failed) == ("dask", len(done_before), n - len(done_before), {})

        deadline = time.monotonic() + 60  # let every orphan finish before counting
        while any(ours(k) for w in c.run(executing).values() for k in w) and time.monotonic() < deadline:
            time.sleep(0.05)
        execs = [k for w in c.run(executed).values() for k in w if ours(k)]
        orphaned = {k for w in c.run(cancelled_running).values() for k in w if ours(k)}

    ev = st.events()
    runs = [e["run"] for e in ev if e["event"] == "run-start"]
    assert len(runs) == 2 and runs[0] == killed
    rerun = runs[1]
    computed = collections.Counter((case_of(k), run_of(k)) for k in execs)
    assert {r for _, r in computed} == {killed, rerun}
    for cid in done_before:  # finished before the kill: computed once, by the killed run
        assert (computed[cid, killed], computed[cid, rerun]) == (1, 0), cid
    for cid in ids - done_before:  # not stored before the kill: computed once by the rerun
        assert computed[cid, rerun] == 1 and computed[cid, killed] <= 1, cid
    # orphans: dropped by the scheduler while running (the driver was gone), then ran to the end
    assert fresh <= orphaned and {run_of(k) for k in orphaned} == {killed}
    assert all(computed[case_of(k), killed] == 1 for k in orphaned)
    assert not {case_of(k) for k in orphaned} & done_before  # their results were never stored

    # stored exactly once: by the killed run (before the kill) or by the rerun (the rest)
    stored = collections.Counter((e["case"], e["run"]) for e in ev if e["event"] == "case-done")
    assert {cid for cid, r in stored if r == rerun} == ids - done_before
    assert {cid for cid, r in stored if r == killed} <= done_before
    assert set(stored.values()) == {1}
    for cid in ids:
        assert st.read_case(cid).attrs["sweep_run"] == (killed if cid in done_before else rerun), cid
    # the orphans, finished now, changed nothing: no late, half-written or duplicate case
    now = {p.name: (p.stat().st_ino, p.stat().st_mtime_ns, p.stat().st_size)
           for p in [*store.joinpath("cases").iterdir(), store / "events.jsonl"]}
    assert now == after_rerun and sorted(now) == sorted([f"{cid}.nc" for cid in ids] + ["events.jsonl"])
    assert sw.status(store)["done"] == n
    by_id = {c.id: c for c in spec.cases}
    for cid in [case_of(k) for k in fresh][:1] + [spec.cases[0].id]:  # an orphaned case and another
        got, ref = st.read_case(cid), direct(by_id[cid].params)
        np.testing.assert_array_equal(got.Fz.values, ref.Fz.values)
        np.testing.assert_array_equal(got.torque.values, ref.torque.values)
